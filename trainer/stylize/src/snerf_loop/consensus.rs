//! Images a round hands to the next one, saved per round so a resumed run continues the same
//! iteration: the consensus targets of `Targets::Consensus` (each round's fused targets, which
//! the next round fuses again; `consensus/round_N/view_III.png`) and the training targets of
//! `StepFrom::Targets` (which the next round's step starts from; `targets/round_N/…`). They
//! are quantized to 8 bits whether saved or not (the field trains on 8-bit targets anyway),
//! so a resumed run and an uninterrupted one compute the same thing.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use crate::stylizer::{image_from_png, save_png, Image};

/// What a saved set of images is.
#[derive(Clone, Copy, Debug)]
pub enum Kept {
    Consensus,
    Targets,
}

fn round_dir(out: &Path, kept: Kept, round: usize) -> PathBuf {
    let name = match kept {
        Kept::Consensus => "consensus",
        Kept::Targets => "targets",
    };
    out.join(name).join(format!("round_{round}"))
}

/// Rounds each value to the nearest of 256 levels in [0, 1], as `save_png` stores it.
pub fn quantize(imgs: Vec<Image>) -> Vec<Image> {
    imgs.into_iter()
        .map(|mut im| {
            for v in &mut im.data {
                *v = ((v.clamp(0.0, 1.0) * 255.0 + 0.5).floor()) / 255.0;
            }
            im
        })
        .collect()
}

/// Saves round `round`'s (1-based) images and removes rounds before `round - 1` (a run
/// killed during round `round` restarts it from round `round - 1`'s).
pub fn save(out: &Path, kept: Kept, round: usize, targets: &[Image]) -> Result<()> {
    let dir = round_dir(out, kept, round);
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    for (i, t) in targets.iter().enumerate() {
        save_png(&dir.join(format!("view_{i:03}.png")), t)?;
    }
    for old in 1..round.saturating_sub(1) {
        let _ = std::fs::remove_dir_all(round_dir(out, kept, old));
    }
    Ok(())
}

/// Round `round`'s images for `views` views, if saved (all of it, or None).
pub fn load(out: &Path, kept: Kept, round: usize, views: usize) -> Result<Option<Vec<Image>>> {
    let dir = round_dir(out, kept, round);
    let mut imgs = Vec::with_capacity(views);
    for i in 0..views {
        let path = dir.join(format!("view_{i:03}.png"));
        if !path.exists() {
            return Ok(None);
        }
        imgs.push(image_from_png(&path)?);
    }
    Ok(Some(imgs))
}
