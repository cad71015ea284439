//! ARCHITECTURE.md stays true: its crate table names exactly the workspace's crates, each
//! with its path and the snerf crates it depends on.

use std::path::Path;

fn workspace_members(root: &Path) -> Vec<String> {
    let toml = std::fs::read_to_string(root.join("Cargo.toml")).unwrap();
    let start = toml.find("members = [").expect("workspace members") + "members = [".len();
    let end = start + toml[start..].find(']').unwrap();
    toml[start..end].split(',').map(|s| s.trim().trim_matches('"').to_string()).filter(|s| !s.is_empty()).collect()
}

fn package_name(dir: &Path) -> String {
    let toml = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
    let pkg = &toml[toml.find("[package]").expect("a [package] section")..];
    let line = pkg.lines().find(|l| l.trim_start().starts_with("name")).unwrap();
    line.split('=').nth(1).unwrap().trim().trim_matches('"').to_string()
}

/// The snerf-* crates in a manifest's `[dependencies]` (not dev- or build-dependencies),
/// without the `snerf-` prefix, sorted.
fn snerf_dependencies(dir: &Path) -> Vec<String> {
    let toml = std::fs::read_to_string(dir.join("Cargo.toml")).unwrap();
    let mut deps: Vec<String> = toml
        .lines()
        .skip_while(|l| l.trim() != "[dependencies]")
        .skip(1)
        .take_while(|l| !l.trim_start().starts_with('['))
        .filter_map(|l| l.trim().strip_prefix("snerf-"))
        .filter_map(|l| l.split([' ', '=']).next())
        .map(str::to_string)
        .collect();
    deps.sort();
    deps
}

#[test]
fn architecture_names_every_crate_and_no_other() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = std::fs::read_to_string(root.join("ARCHITECTURE.md")).expect("ARCHITECTURE.md at the root");
    // Table rows: | name | path | ...
    let table: Vec<(String, String)> = doc
        .lines()
        .filter(|l| l.starts_with("| snerf"))
        .map(|l| {
            let cols: Vec<&str> = l.split('|').map(str::trim).collect();
            (cols[1].to_string(), cols[2].to_string())
        })
        .collect();
    let mut crates: Vec<(String, String)> =
        workspace_members(root).into_iter().map(|m| (package_name(&root.join(&m)), m)).collect();
    crates.push((package_name(root), ".".to_string()));
    for (name, path) in &crates {
        let row = table.iter().find(|(n, _)| n == name);
        assert!(row.is_some(), "ARCHITECTURE.md has no row for crate {name} ({path})");
        let p = &row.unwrap().1;
        assert!(p == path || p.starts_with(&format!("{path} ")), "ARCHITECTURE.md puts {name} at {p}, it is at {path}");
    }
    for (name, _) in &table {
        assert!(crates.iter().any(|(n, _)| n == name), "ARCHITECTURE.md names {name}, which is not a workspace crate");
    }
}

#[test]
fn architecture_says_what_each_crate_depends_on() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = std::fs::read_to_string(root.join("ARCHITECTURE.md")).expect("ARCHITECTURE.md at the root");
    let mut checked = 0;
    for l in doc.lines().filter(|l| l.starts_with("| snerf")) {
        let cols: Vec<&str> = l.split('|').map(str::trim).collect();
        let (name, path, deps) = (cols[1], cols[2].split(' ').next().unwrap(), cols[4]);
        if deps == "all of the above" {
            continue;
        }
        let mut said: Vec<String> = deps.split(',').map(str::trim).filter(|d| !d.is_empty() && *d != "—").map(str::to_string).collect();
        said.sort();
        assert_eq!(said, snerf_dependencies(&root.join(path)), "ARCHITECTURE.md: what {name} depends on");
        checked += 1;
    }
    assert!(checked >= 10, "only {checked} rows with dependencies found");
}
