//! What COLMAP's mapper produced: it may write several disconnected models (`sparse/0`,
//! `sparse/1`, ...) when the photos fall into groups it cannot join; the capture keeps the one
//! with the most registered images and reports every other photo as not registered.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};

use crate::colmap::{read_images_bin, read_images_txt};

/// One model folder and the image names it registered.
#[derive(Clone, Debug)]
pub struct Model {
    pub dir: PathBuf,
    pub registered: Vec<String>,
    /// How many models the mapper wrote in all.
    pub models_found: usize,
}

/// The model under `sparse` with the most registered images.
pub fn largest(sparse: &Path) -> Result<Model> {
    let rd = std::fs::read_dir(sparse)
        .map_err(|e| anyhow!("{}: cannot list the mapper's output: {e}", sparse.display()))?;
    let mut best: Option<Model> = None;
    let mut found = 0;
    let mut dirs: Vec<PathBuf> = rd
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_dir())
        .collect();
    dirs.sort();
    for d in dirs {
        let names = match registered_names(&d) {
            Ok(n) => n,
            Err(_) => continue,
        };
        found += 1;
        if best
            .as_ref()
            .is_none_or(|b| names.len() > b.registered.len())
        {
            best = Some(Model {
                dir: d,
                registered: names,
                models_found: 0,
            });
        }
    }
    match best {
        Some(mut m) => {
            m.models_found = found;
            Ok(m)
        }
        None => bail!(
            "COLMAP's mapper built no model: it found no pair of photos with enough matched \
             features and baseline to start from (more overlap between photos, more texture, \
             or --matcher exhaustive may help)"
        ),
    }
}

/// The image names in a model folder (`images.bin` or `images.txt`).
pub fn registered_names(dir: &Path) -> Result<Vec<String>> {
    let bin = dir.join("images.bin");
    let imgs = if bin.is_file() {
        let bytes =
            std::fs::read(&bin).map_err(|e| anyhow!("{}: cannot read: {e}", bin.display()))?;
        read_images_bin(&bytes).map_err(|e| anyhow!("{}: {e}", bin.display()))?
    } else {
        let txt = dir.join("images.txt");
        let text = std::fs::read_to_string(&txt)
            .map_err(|e| anyhow!("{}: cannot read: {e}", txt.display()))?;
        read_images_txt(&text).map_err(|e| anyhow!("{}: {e}", txt.display()))?
    };
    let mut names: Vec<String> = imgs.into_iter().map(|i| i.name).collect();
    names.sort();
    Ok(names)
}

/// "Mean reprojection error: 0.335144px" in `colmap model_analyzer`'s output.
pub fn parse_reprojection_error(log: &str) -> Option<f64> {
    log.lines().find_map(|l| {
        let rest = l.split("Mean reprojection error:").nth(1)?;
        rest.trim().trim_end_matches("px").trim().parse().ok()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reprojection_error_line_parses() {
        let log = "Points: 3508\nI20261206 analyzer.cc:1] Mean reprojection error: 0.335144px\n";
        assert_eq!(parse_reprojection_error(log), Some(0.335144));
        assert_eq!(parse_reprojection_error("Points: 3"), None);
    }
}
