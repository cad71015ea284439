//! Which dataset format a path holds: transforms.json (Blender / nerfstudio), LLFF
//! `poses_bounds.npy`, or a COLMAP sparse model; a file or a directory may be given.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};

#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Source {
    /// (split name, file): one `("all", transforms.json)` or the `transforms_{split}.json` present.
    Transforms { files: Vec<(String, PathBuf)> },
    /// The directory holding `poses_bounds.npy` and `images/`.
    Llff { dir: PathBuf },
    /// The directory holding `cameras.{bin,txt}` and `images.{bin,txt}`.
    Colmap { model_dir: PathBuf },
}

const SPLITS: [&str; 3] = ["train", "val", "test"];

pub(crate) fn locate(path: &Path) -> Result<Source> {
    if !path.exists() {
        bail!("{}: no such file or directory", path.display());
    }
    if path.is_file() {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let dir = parent_dir(path);
        if name.ends_with(".json") {
            if SPLITS
                .iter()
                .any(|s| name == format!("transforms_{s}.json"))
            {
                return Ok(Source::Transforms {
                    files: split_files(&dir),
                });
            }
            return Ok(Source::Transforms {
                files: vec![("all".into(), path.to_path_buf())],
            });
        }
        if name.ends_with(".npy") {
            return Ok(Source::Llff { dir });
        }
        if ["cameras.bin", "cameras.txt", "images.bin", "images.txt"].contains(&name) {
            if !is_colmap_dir(&dir) {
                bail!("{}: COLMAP model incomplete: need both cameras.{{bin,txt}} and images.{{bin,txt}} in {}", path.display(), dir.display());
            }
            return Ok(Source::Colmap { model_dir: dir });
        }
        bail!(
            "{}: unrecognised dataset file (expected transforms*.json, poses_bounds.npy, or a COLMAP cameras/images file)",
            path.display()
        );
    }
    let dir = path;
    if dir.join("transforms_train.json").is_file() {
        return Ok(Source::Transforms {
            files: split_files(dir),
        });
    }
    if dir.join("transforms.json").is_file() {
        return Ok(Source::Transforms {
            files: vec![("all".into(), dir.join("transforms.json"))],
        });
    }
    if dir.join("poses_bounds.npy").is_file() {
        return Ok(Source::Llff {
            dir: dir.to_path_buf(),
        });
    }
    for cand in [
        dir.join("sparse").join("0"),
        dir.join("sparse"),
        dir.to_path_buf(),
    ] {
        if is_colmap_dir(&cand) {
            return Ok(Source::Colmap { model_dir: cand });
        }
    }
    bail!(
        "{}: no dataset found: expected transforms.json, transforms_train.json, poses_bounds.npy, \
         or a COLMAP model (sparse/0/cameras.bin + images.bin, or .txt)",
        dir.display()
    )
}

fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

fn split_files(dir: &Path) -> Vec<(String, PathBuf)> {
    SPLITS
        .iter()
        .map(|s| (s.to_string(), dir.join(format!("transforms_{s}.json"))))
        .filter(|(_, p)| p.is_file())
        .collect()
}

fn is_colmap_dir(dir: &Path) -> bool {
    let has = |stem: &str| {
        dir.join(format!("{stem}.bin")).is_file() || dir.join(format!("{stem}.txt")).is_file()
    };
    has("cameras") && has("images")
}
