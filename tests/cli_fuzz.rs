//! A property test over the command line's argument space: random flags and values (valid,
//! out of range, non-finite, not numbers) on a tiny dataset, run, and baked asset. No
//! combination may panic, and every `--json` output — success or error — must be JSON with
//! only finite numbers. Deterministic: the seed is fixed and printed with each case.
mod common;
use common::snerf;

use std::path::{Path, PathBuf};

use snerf_files::ScratchDir;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn pick<'a>(&mut self, xs: &[&'a str]) -> &'a str {
        xs[(self.next() % xs.len() as u64) as usize]
    }
}

/// Values that must be refused wherever a number is expected.
const WILD: &[&str] = &["NaN", "inf", "-inf", "-1", "abc", "", "1e400", "18446744073709551616", "0x10"];

fn finite_everywhere(v: &serde_json::Value) -> bool {
    match v {
        serde_json::Value::Number(n) => n.as_f64().is_some_and(f64::is_finite),
        serde_json::Value::Array(a) => a.iter().all(finite_everywhere),
        serde_json::Value::Object(o) => o.values().all(finite_everywhere),
        _ => true,
    }
}

struct Case {
    args: Vec<String>,
}

fn case(rng: &mut Rng, ds: &Path, run: &Path, asset: &Path, out: &Path) -> Case {
    let p = |x: &Path| x.to_string_lossy().to_string();
    // (base arguments, flags with the valid values worth trying; cheap values only, so a
    // case never runs for long)
    type Row<'a> = (Vec<String>, Vec<(&'a str, Vec<&'a str>)>);
    let table: Vec<Row> = vec![
        (
            vec!["train".into(), p(ds), "--out".into(), p(&out.join("r")), "--minutes".into(), "0.01".into()],
            vec![
                ("--steps", vec!["1", "3"]),
                ("--lr-planes", vec!["0.04", "1e-9", "100"]),
                ("--lr-mlp", vec!["0.01", "1e30"]),
                ("--tv", vec!["0", "1"]),
                ("--distortion", vec!["0", "0.1"]),
                ("--resolution", vec!["16", "64", "15"]),
                ("--batch", vec!["64", "100"]),
                ("--batch-samples", vec!["1024", "5000"]),
                ("--curve-pixels", vec!["0", "10"]),
                ("--checkpoint-every", vec!["0", "1"]),
                ("--downscale", vec!["1", "2", "64"]),
                ("--kind", vec!["object", "forward", "unbounded", "planet"]),
            ],
        ),
        (
            vec!["eval".into(), p(run), p(ds), "--out".into(), p(&out.join("e"))],
            vec![("--split", vec!["test", "train", "val", "x"]), ("--downscale", vec!["1", "2"])],
        ),
        (
            vec!["turntable".into(), p(run), p(ds), "--out".into(), p(&out.join("t"))],
            vec![("--frames", vec!["1", "2", "0", "3601"])],
        ),
        (
            vec!["bake".into(), p(run), "--data".into(), p(ds), "--out".into(), p(&out.join("b.snerf")), "--resolution".into(), "32".into()],
            vec![
                ("--block", vec!["4", "8", "3", "65"]),
                ("--keyframes", vec!["1", "0"]),
                ("--min-alpha", vec!["0", "0.5", "1", "1.5"]),
                ("--reuse-tolerance", vec!["0", "0.03"]),
                ("--time-budget", vec!["1.8", "0", "1e9", "nan"]),
                ("--motion", vec!["false", "true", "maybe"]),
                ("--motion-references", vec!["1", "3", "0", "65"]),
                ("--visibility-views", vec!["0", "2"]),
                ("--eval-views", vec!["0", "1"]),
            ],
        ),
        (vec!["inspect".into(), p(asset)], vec![]),
        (
            vec!["render".into(), p(asset), "--out".into(), p(&out.join("f"))],
            vec![("--frames", vec!["1", "2", "0", "10001"]), ("--size", vec!["8x8", "16x12", "0x0", "9000x9000", "axb"])],
        ),
        (
            vec!["export-gltf".into(), p(asset), "--out".into(), p(&out.join("m.glb"))],
            vec![("--iso", vec!["0.5", "0", "1", "0.01"])],
        ),
        (
            vec![
                "stylize".into(),
                p(run),
                "--data".into(),
                p(ds),
                "--out".into(),
                p(&out.join("s")),
                "--stylizer".into(),
                "color".into(),
                "--style".into(),
                p(&ds.join("train/r_000.png")),
                "--consistency-frames".into(),
                "0".into(),
            ],
            vec![
                ("--rounds", vec!["1", "0", "101"]),
                ("--steps-per-round", vec!["1", "2", "0"]),
                ("--style-res", vec!["0", "16", "4097"]),
                ("--views", vec!["0", "2"]),
                ("--strength", vec!["0", "0.5", "1", "2"]),
            ],
        ),
        (
            vec!["scene".into(), "object".into(), "--out".into(), p(&out.join("ds")), "--size".into(), "8x8".into()],
            vec![
                ("--views", vec!["1", "2", "0"]),
                ("--test-views", vec!["1", "0"]),
                ("--supersample", vec!["1", "2", "0", "17"]),
                ("--path", vec!["sphere", "orbit", "line"]),
            ],
        ),
        (vec!["data".into(), p(ds)], vec![("--holdout-every", vec!["2", "0", "1"]), ("--downscale", vec!["1", "0"])]),
    ];
    let (base, flags) = &table[(rng.next() % table.len() as u64) as usize];
    let mut args = vec!["--json".to_string()];
    if rng.next().is_multiple_of(4) {
        args.extend(["--threads".to_string(), rng.pick(&["1", "2", "0", "100000", "NaN"]).to_string()]);
    }
    args.extend(base.iter().cloned());
    for (flag, valid) in flags {
        if rng.next().is_multiple_of(2) {
            continue;
        }
        let v = if rng.next().is_multiple_of(3) { rng.pick(WILD) } else { rng.pick(valid) };
        args.push(flag.to_string());
        args.push(v.to_string());
    }
    Case { args }
}

fn prepare(d: &Path) -> (PathBuf, PathBuf, PathBuf) {
    let ds = d.join("ds");
    let run = d.join("run");
    let asset = d.join("a.snerf");
    let check = |out: std::process::Output| {
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    };
    check(snerf().args(["scene", "object", "--views", "6", "--test-views", "2", "--size", "16x16", "--supersample", "1", "--out"]).arg(&ds).output().unwrap());
    check(snerf().arg("train").arg(&ds).arg("--out").arg(&run).args(["--steps", "3"]).output().unwrap());
    check(snerf().arg("bake").arg(&run).arg("--out").arg(&asset).args(["--resolution", "32", "--eval-views", "1", "--visibility-views", "4"]).output().unwrap());
    (ds, run, asset)
}

#[test]
fn random_command_lines_never_panic_and_json_stays_finite() {
    let d = ScratchDir::new("snerf-fuzz", "cases").unwrap();
    let (ds, run, asset) = prepare(&d);
    let cases: usize = std::env::var("SNERF_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(60);
    let mut rng = Rng(0x5eed_cafe_f00d_1234);
    let (mut succeeded, mut refused) = (0, 0);
    for i in 0..cases {
        let out_dir = d.join(format!("case{i}"));
        let c = case(&mut rng, &ds, &run, &asset, &out_dir);
        let out = snerf().args(&c.args).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let shown = format!("case {i}: snerf {}", c.args.join(" "));
        assert_ne!(out.status.code(), Some(101), "{shown}\n{stderr}");
        assert!(!stderr.contains("panicked"), "{shown}\n{stderr}");
        let v: serde_json::Value = serde_json::from_slice(&out.stdout)
            .unwrap_or_else(|e| panic!("{shown}: stdout is not JSON ({e}): {}\n{stderr}", String::from_utf8_lossy(&out.stdout)));
        assert!(finite_everywhere(&v), "{shown}: non-finite number in {v}");
        if out.status.success() {
            succeeded += 1;
            assert!(v.get("error").is_none(), "{shown}: {v}");
        } else {
            refused += 1;
            assert!(v["error"].as_str().is_some_and(|e| !e.is_empty()), "{shown}: an error without a message: {v}");
        }
        let _ = std::fs::remove_dir_all(&out_dir);
    }
    println!("{cases} random command lines: {succeeded} ran, {refused} refused with a JSON error");
    assert!(succeeded > 0 && refused > 0, "the generator should produce both ({succeeded}, {refused})");
}
