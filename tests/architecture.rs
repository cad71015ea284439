//! ARCHITECTURE.md stays true: its crate table names exactly the workspace's crates, each
//! with its path.

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
