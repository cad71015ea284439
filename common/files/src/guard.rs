//! One output-path guard for every command, and ownership manifests.
//!
//! `check_output` refuses an output that is one of the command's input files (by path, by
//! symlink or by hard link) or that lies inside an input tree (a dataset, a run), so
//! `bake R --out R/checkpoint.snerfck` or `train ds --out ds` fail before anything is written.
//!
//! A command that replaces a whole directory (`snerf scene`) may do so only when the
//! directory's manifest (`.snerf-manifest.json`, written last by the command that created it)
//! lists exactly the files in it, with their sizes: proof that snerf wrote everything there
//! and the user added or changed nothing.

use std::collections::BTreeMap;
use std::path::{Component, Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

/// An input of a command, as far as where it may write is concerned.
#[derive(Clone, Copy, Debug)]
pub enum Input<'a> {
    /// A file that must not be written.
    File(&'a Path),
    /// A directory nothing may be written into (a dataset, a source run).
    Tree(&'a Path),
}

/// `path` made absolute with symlinks resolved, for the part of it that exists; the rest
/// is appended lexically (with `..` applied).
pub fn resolve(path: &Path) -> PathBuf {
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        std::env::current_dir().unwrap_or_default().join(path)
    };
    let mut existing = abs.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(mut out) = std::fs::canonicalize(existing) {
            for part in rest.iter().rev() {
                match part {
                    Component::ParentDir => {
                        out.pop();
                    }
                    Component::CurDir => {}
                    p => out.push(p.as_os_str()),
                }
            }
            return out;
        }
        match (existing.components().next_back(), existing.parent()) {
            (Some(last), Some(parent)) => {
                rest.push(last);
                existing = parent;
            }
            _ => return abs,
        }
    }
}

#[cfg(unix)]
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_file(_: &Path, _: &Path) -> bool {
    false
}

/// Refuse an output (`flag` names it in the message, e.g. "--out") that would overwrite or
/// land inside one of `inputs`. Inputs that do not exist are ignored.
pub fn check_output(flag: &str, out: &Path, inputs: &[Input]) -> Result<()> {
    let o = resolve(out);
    for input in inputs {
        match *input {
            Input::File(f) => {
                if !f.exists() {
                    continue;
                }
                if resolve(f) == o || same_file(f, out) {
                    bail!(
                        "{flag} {}: that is the input {}; writing it would destroy the input (choose another {flag})",
                        out.display(),
                        f.display()
                    );
                }
            }
            Input::Tree(d) => {
                if !d.exists() {
                    continue;
                }
                let rd = resolve(d);
                if o == rd || o.starts_with(&rd) {
                    bail!(
                        "{flag} {}: that is {} the input {}; snerf never writes into its inputs (choose another {flag})",
                        out.display(),
                        if o == rd { "the same directory as" } else { "inside" },
                        d.display()
                    );
                }
            }
        }
    }
    Ok(())
}

pub const MANIFEST: &str = ".snerf-manifest.json";

#[derive(Serialize, Deserialize)]
struct Manifest {
    written_by: String,
    /// Relative path (with `/`) -> size in bytes, of every file below the directory.
    files: BTreeMap<String, u64>,
}

/// What a directory is, for a command that wants to replace it.
#[derive(Debug, PartialEq)]
pub enum Ownership {
    Missing,
    Empty,
    /// snerf wrote every file in it (its manifest says so and nothing was added or changed).
    Owned,
    /// Not provably snerf's: the reason names a file.
    Foreign(String),
}

fn list_files(dir: &Path) -> Result<BTreeMap<String, u64>> {
    fn walk(root: &Path, dir: &Path, out: &mut BTreeMap<String, u64>) -> Result<()> {
        for e in std::fs::read_dir(dir).with_context(|| format!("{}: cannot read", dir.display()))? {
            let e = e.with_context(|| format!("{}: cannot read", dir.display()))?;
            let t = e.file_type()?;
            let p = e.path();
            if t.is_dir() {
                walk(root, &p, out)?;
            } else {
                let rel = p.strip_prefix(root).unwrap_or(&p);
                let key = rel.components().map(|c| c.as_os_str().to_string_lossy()).collect::<Vec<_>>().join("/");
                let len = if t.is_symlink() { u64::MAX } else { e.metadata()?.len() };
                out.insert(key, len);
            }
        }
        Ok(())
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out)?;
    Ok(out)
}

/// Record every file now under `dir` as written by `tool` (call it last, after the files).
pub fn write_manifest(dir: &Path, tool: &str) -> Result<()> {
    let mut files = list_files(dir)?;
    files.remove(MANIFEST);
    crate::atomic::write_json_atomic(&dir.join(MANIFEST), &Manifest { written_by: tool.into(), files })
}

/// Whether `dir` may be replaced by a command that wrote it.
pub fn ownership(dir: &Path) -> Result<Ownership> {
    let meta = match std::fs::symlink_metadata(dir) {
        Err(_) => return Ok(Ownership::Missing),
        Ok(m) => m,
    };
    if !meta.is_dir() {
        return Ok(Ownership::Foreign(format!("{} is not a directory", dir.display())));
    }
    let mut files = list_files(dir)?;
    if files.is_empty() {
        return Ok(Ownership::Empty); // no files at all (empty folders hold nothing to lose)
    }
    let Some(_) = files.remove(MANIFEST) else {
        return Ok(Ownership::Foreign(format!("it has no {MANIFEST}, so snerf cannot tell that it wrote the files there")));
    };
    let m: Manifest = match std::fs::read(dir.join(MANIFEST)).ok().and_then(|b| serde_json::from_slice(&b).ok()) {
        Some(m) => m,
        None => return Ok(Ownership::Foreign(format!("its {MANIFEST} is unreadable"))),
    };
    for (name, len) in &files {
        match m.files.get(name) {
            None => return Ok(Ownership::Foreign(format!("{name} was not written by {}", m.written_by))),
            Some(l) if l != len => return Ok(Ownership::Foreign(format!("{name} changed since {} wrote it", m.written_by))),
            Some(_) => {}
        }
    }
    Ok(Ownership::Owned)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> crate::ScratchDir {
        crate::ScratchDir::new("snerf-guard", tag).unwrap()
    }

    #[test]
    fn outputs_may_not_be_inputs_or_inside_input_trees() {
        let d = scratch("inputs");
        let run = d.join("run");
        std::fs::create_dir_all(&run).unwrap();
        let ck = run.join("checkpoint.snerfck");
        std::fs::write(&ck, b"x").unwrap();
        let ds = d.join("ds");
        std::fs::create_dir_all(ds.join("train")).unwrap();
        let ins = [Input::File(&ck), Input::Tree(&ds)];
        assert!(check_output("--out", &ck, &ins).is_err());
        assert!(check_output("--out", &run.join("../run/./checkpoint.snerfck"), &ins).is_err());
        assert!(check_output("--out", &ds, &ins).is_err());
        assert!(check_output("--out", &ds.join("train/new/x.png"), &ins).is_err());
        assert!(check_output("--out", &run.join("scene.snerf"), &ins).is_ok());
        assert!(check_output("--out", &d.join("dsx"), &ins).is_ok());
        // a hard link and a symlink to the input are the input
        let hard = d.join("hard");
        std::fs::hard_link(&ck, &hard).unwrap();
        assert!(check_output("--out", &hard, &ins).is_err());
        #[cfg(unix)]
        {
            let soft = d.join("soft");
            std::os::unix::fs::symlink(&ck, &soft).unwrap();
            assert!(check_output("--out", &soft, &ins).is_err());
        }
    }

    #[test]
    fn only_a_directory_snerf_wrote_entirely_is_owned() {
        let d = scratch("own");
        let ds = d.join("ds");
        assert_eq!(ownership(&ds).unwrap(), Ownership::Missing);
        std::fs::create_dir_all(ds.join("train")).unwrap();
        assert_eq!(ownership(&ds).unwrap(), Ownership::Empty);
        std::fs::write(ds.join("train/r_000.png"), b"png").unwrap();
        std::fs::write(ds.join("transforms_train.json"), b"{}").unwrap();
        assert!(matches!(ownership(&ds).unwrap(), Ownership::Foreign(_)));
        write_manifest(&ds, "snerf scene").unwrap();
        assert_eq!(ownership(&ds).unwrap(), Ownership::Owned);
        std::fs::write(ds.join("train/IMG_precious.png"), b"mine").unwrap();
        assert!(matches!(ownership(&ds).unwrap(), Ownership::Foreign(m) if m.contains("IMG_precious")));
        std::fs::remove_file(ds.join("train/IMG_precious.png")).unwrap();
        std::fs::write(ds.join("train/r_000.png"), b"edited by the user").unwrap();
        assert!(matches!(ownership(&ds).unwrap(), Ownership::Foreign(m) if m.contains("changed")));
    }
}
