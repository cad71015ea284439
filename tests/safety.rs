//! Nothing lost, nothing faked: each test here reproduces a way a realistic (or hostile) user
//! could lose data or be told a failure was a success, and checks the command now refuses
//! clearly, exits honestly and leaves every file it did not create alone.
mod common;
use common::{fails, ok, snerf};

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use snerf_files::ScratchDir;

/// This test's directory: removed when it passes, kept (and named) when it fails.
fn tmp(name: &str) -> ScratchDir {
    ScratchDir::new("snerf-safety", name).unwrap()
}

fn dataset(dir: &Path, views: usize, size: &str) {
    ok(snerf()
        .args(["--json", "scene", "object", "--out"])
        .arg(dir)
        .args(["--views", &views.to_string(), "--test-views", "2", "--size", size, "--supersample", "1"])
        .output()
        .unwrap());
}

fn train(data: &Path, run: &Path, steps: u32) {
    ok(snerf().args(["--json", "train"]).arg(data).arg("--out").arg(run).args(["--steps", &steps.to_string()]).output().unwrap());
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn scene_never_deletes_a_directory_it_did_not_write() {
    let d = tmp("scene");
    let cap = d.join("cap");
    std::fs::create_dir_all(cap.join("train")).unwrap();
    std::fs::write(cap.join("train/IMG_precious.png"), b"a photo").unwrap();
    std::fs::write(cap.join("transforms_train.json"), br#"{"camera_angle_x":0.69,"frames":[]}"#).unwrap();
    fails(
        snerf().args(["scene", "object", "--out"]).arg(&cap).args(["--size", "16x16", "--views", "2"]).output().unwrap(),
        &["cap", "cannot replace"],
    );
    assert_eq!(bytes(&cap.join("train/IMG_precious.png")), b"a photo");
    // its own dataset it replaces; a leftover temp directory of a killed `scene` is swept
    let ds = d.join("ds");
    dataset(&ds, 2, "16x16");
    let stale = d.join(".ds.4999999.snerf-tmp");
    std::fs::create_dir_all(stale.join("train")).unwrap();
    std::fs::write(stale.join("train/r_000.png"), vec![0u8; 1000]).unwrap();
    dataset(&ds, 3, "16x16");
    assert!(!stale.exists(), "the stale temp directory of a dead process is removed");
    assert!(ds.join("train/r_002.png").exists());
    fails(snerf().args(["scene", "object", "--test-views", "0", "--out"]).arg(d.join("t0")).output().unwrap(), &["--test-views"]);
    assert!(!d.join("t0").exists());
}

#[test]
fn outputs_never_overwrite_inputs() {
    let d = tmp("inputs");
    let ds = d.join("ds");
    dataset(&ds, 6, "24x24");
    let before = bytes(&ds.join("transforms_train.json"));
    fails(snerf().arg("train").arg(&ds).arg("--out").arg(&ds).args(["--steps", "2"]).output().unwrap(), &["--out", "ds"]);
    fails(snerf().arg("train").arg(&ds).arg("--out").arg(ds.join("run")).args(["--steps", "2"]).output().unwrap(), &["inside"]);
    assert_eq!(bytes(&ds.join("transforms_train.json")), before);
    assert!(!ds.join("run").exists() && !ds.join("checkpoint.snerfck").exists());

    let run = d.join("run");
    train(&ds, &run, 3);
    let ck = run.join("checkpoint.snerfck");
    let ck_bytes = bytes(&ck);
    fails(
        snerf().arg("bake").arg(&run).arg("--out").arg(&ck).args(["--resolution", "32", "--eval-views", "0"]).output().unwrap(),
        &["checkpoint.snerfck", "input"],
    );
    fails(
        snerf().arg("stylize").arg(&run).arg("--out").arg(&run).args(["--stylizer", "color", "--style"]).arg(ds.join("train/r_000.png")).output().unwrap(),
        &["--out"],
    );
    fails(snerf().arg("eval").arg(&run).arg(&ds).arg("--out").arg(ds.join("train")).output().unwrap(), &["inside"]);
    assert_eq!(bytes(&ck), ck_bytes, "the run's checkpoint is untouched");

    let asset = d.join("x.snerf");
    ok(snerf()
        .args(["--json", "bake"])
        .arg(&run)
        .arg("--out")
        .arg(&asset)
        .args(["--resolution", "32", "--eval-views", "0", "--visibility-views", "4"])
        .output()
        .unwrap());
    let asset_bytes = bytes(&asset);
    fails(snerf().arg("export-gltf").arg(&asset).arg("--out").arg(&asset).output().unwrap(), &["x.snerf", "input"]);
    // a hard link to the asset is the asset
    let link = d.join("link.glb");
    std::fs::hard_link(&asset, &link).unwrap();
    fails(snerf().arg("export-gltf").arg(&asset).arg("--out").arg(&link).output().unwrap(), &["input"]);
    assert_eq!(bytes(&asset), asset_bytes);
    fails(snerf().arg("render").arg(&asset).arg("--out").arg(&asset).output().unwrap(), &["input"]);
    assert_eq!(bytes(&asset), asset_bytes);
    let img = ds.join("train/r_000.png");
    let img_bytes = bytes(&img);
    fails(snerf().args(["stylize-image"]).arg(&img).args(["--stylizer", "color", "--style"]).arg(&img).arg("--out").arg(&img).output().unwrap(), &["input"]);
    assert_eq!(bytes(&img), img_bytes);
}

#[test]
fn non_finite_numbers_are_refused_and_divergence_is_reported() {
    let d = tmp("nan");
    let ds = d.join("ds");
    dataset(&ds, 6, "24x24");
    for (flag, v) in [("--lr-mlp", "NaN"), ("--lr-planes", "inf"), ("--tv", "NaN"), ("--distortion", "-1"), ("--minutes", "NaN"), ("--steps", "0")] {
        fails(snerf().arg("train").arg(&ds).arg("--out").arg(d.join("r")).arg(format!("{flag}={v}")).output().unwrap(), &[flag]);
    }
    assert!(!d.join("r").exists(), "nothing written for a refused command line");
    fails(snerf().args(["view", "x.snerf", "--ipd", "NaN"]).output().unwrap(), &["--ipd"]);
    fails(snerf().args(["bake", "r", "--out", "x.snerf", "--min-alpha", "nan"]).output().unwrap(), &["--min-alpha"]);
    fails(snerf().args(["stylize", "r", "--out", "s", "--rounds", "0"]).output().unwrap(), &["--rounds"]);
    fails(snerf().args(["stylize", "r", "--out", "s", "--style-res", "100000"]).output().unwrap(), &["--style-res"]);
    fails(snerf().args(["--threads", "100000", "inspect", "x.snerf"]).output().unwrap(), &["--threads", "cores"]);

    // a learning rate that blows the field up: an honest error, never "120 dB"
    let out = snerf().args(["--json", "train"]).arg(&ds).arg("--out").arg(d.join("div")).args(["--steps", "20", "--lr-mlp", "1e11", "--lr-planes", "1e11"]).output().unwrap();
    let stderr = fails(out.clone(), &["diverged"]);
    assert!(!stderr.contains("120.00"), "{stderr}");
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("--json errors are JSON on stdout");
    assert!(v["error"].as_str().unwrap().contains("diverged"), "{v}");
}

#[test]
fn ctrl_c_saves_the_run_and_exits_non_zero() {
    let d = tmp("sigint");
    let ds = d.join("ds");
    dataset(&ds, 8, "24x24");
    let run = d.join("run");
    let child = snerf()
        .arg("train")
        .arg(&ds)
        .arg("--out")
        .arg(&run)
        .args(["--minutes", "5", "--checkpoint-every", "100000"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // wait until training has started (the run is locked), then a moment more
    let t0 = Instant::now();
    while !run.join(".snerf-lock").exists() && t0.elapsed() < Duration::from_secs(60) {
        std::thread::sleep(Duration::from_millis(100));
    }
    std::thread::sleep(Duration::from_secs(3));
    // a second training into the same directory is refused while the first runs
    fails(snerf().arg("train").arg(&ds).arg("--out").arg(&run).args(["--steps", "2", "--resume"]).output().unwrap(), &["in use"]);
    // Two signals at once, as `timeout -s INT` or a terminal delivers one to the process and
    // one to its group: still one request, and the run is saved.
    for _ in 0..2 {
        let st = Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap();
        assert!(st.success());
    }
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("interrupted") && stderr.contains("--resume"), "{stderr}");
    let m: serde_json::Value = serde_json::from_slice(&bytes(&run.join("metrics.json"))).unwrap();
    let step = m["step"].as_u64().unwrap();
    assert!(step > 0, "{m}");
    // the resumed run continues from there
    let r = ok(snerf().args(["--json", "train"]).arg(&ds).arg("--out").arg(&run).args(["--resume", "--steps", &(step + 3).to_string()]).output().unwrap());
    assert_eq!(r["metrics"]["step"].as_u64(), Some(step + 3), "{r}");
    let names: Vec<String> = std::fs::read_dir(&run).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into()).collect();
    assert!(names.iter().all(|n| !n.ends_with("tmp")), "{names:?}");
}

#[test]
fn stale_temp_files_are_swept_and_resume_is_honest() {
    let d = tmp("stale");
    let ds = d.join("ds");
    dataset(&ds, 6, "24x24");
    let run = d.join("run");
    fails(snerf().arg("train").arg(&ds).arg("--out").arg(&run).args(["--resume", "--steps", "2"]).output().unwrap(), &["nothing to resume"]);
    train(&ds, &run, 3);
    // temp files a killed process left (dead PIDs: above the kernel's pid_max)
    let stale = [run.join(".checkpoint.snerfck.4999999.snerf-tmp"), run.join("checkpoint.snerfck.4999998.tmp")];
    for s in &stale {
        std::fs::write(s, vec![0u8; 4096]).unwrap();
    }
    let user_file = run.join("notes.4999999.tmp");
    std::fs::write(&user_file, b"mine").unwrap();
    // a conflicting architecture on resume is refused, not ignored
    fails(snerf().arg("train").arg(&ds).arg("--out").arg(&run).args(["--resume", "--steps", "5", "--resolution", "128"]).output().unwrap(), &["--resolution", "resumed"]);
    train_resume(&ds, &run, 5);
    for s in &stale {
        assert!(!s.exists(), "{} should have been swept", s.display());
    }
    assert!(user_file.exists(), "a file snerf did not name is never swept");
}

fn train_resume(data: &Path, run: &Path, steps: u32) {
    ok(snerf().args(["--json", "train"]).arg(data).arg("--out").arg(run).args(["--resume", "--steps", &steps.to_string()]).output().unwrap());
}


#[test]
fn impossible_inputs_are_refused_not_accepted_silently() {
    let d = tmp("silent");
    let ds = d.join("ds");
    dataset(&ds, 6, "24x24");
    // a checkpoint with a valid checksum and an impossible setting (chunk_rays = 0)
    let run = d.join("run");
    train(&ds, &run, 2);
    let ck = run.join("checkpoint.snerfck");
    let b = bytes(&ck);
    let hlen = u64::from_le_bytes(b[12..20].try_into().unwrap()) as usize;
    let mut header: serde_json::Value = serde_json::from_slice(&b[20..20 + hlen]).unwrap();
    header["cfg"]["chunk_rays"] = 0.into();
    let hbytes = serde_json::to_vec(&header).unwrap();
    let mut nb = b[..12].to_vec();
    nb.extend_from_slice(&(hbytes.len() as u64).to_le_bytes());
    nb.extend_from_slice(&hbytes);
    nb.extend_from_slice(&b[20 + hlen..b.len() - 8]);
    let sum = snerf_trainer::checkpoint::checksum(&nb);
    nb.extend_from_slice(&sum.to_le_bytes());
    std::fs::write(&ck, &nb).unwrap();
    fails(snerf().arg("train").arg(&ds).arg("--out").arg(&run).args(["--resume", "--steps", "4"]).output().unwrap(), &["chunk_rays"]);

    // cameras far outside any scene: an error, not a "trained" run that saw nothing
    let far = d.join("far");
    dataset(&far, 6, "24x24");
    for split in ["train", "val", "test"] {
        let f = far.join(format!("transforms_{split}.json"));
        let mut v: serde_json::Value = serde_json::from_slice(&bytes(&f)).unwrap();
        for fr in v["frames"].as_array_mut().unwrap() {
            for r in 0..3 {
                fr["transform_matrix"][r][3] = 1e30.into();
            }
        }
        v.as_object_mut().unwrap().remove("aabb");
        std::fs::write(&f, serde_json::to_vec(&v).unwrap()).unwrap();
    }
    let out = snerf().arg("train").arg(&far).arg("--out").arg(d.join("farrun")).args(["--steps", "200"]).output().unwrap();
    fails(out, &[]);

    // a camera file with fx = 0, and more frames than a render may hold
    let run2 = d.join("run2");
    train(&ds, &run2, 2);
    let asset = d.join("a.snerf");
    ok(snerf()
        .args(["--json", "bake"])
        .arg(&run2)
        .arg("--out")
        .arg(&asset)
        .args(["--resolution", "32", "--eval-views", "0", "--visibility-views", "4"])
        .output()
        .unwrap());
    let cams = d.join("cams.json");
    std::fs::write(&cams, r#"[{"c2w":[[1,0,0,0],[0,1,0,0],[0,0,1,3]],"fx":0,"fy":10,"cx":8,"cy":8,"width":16,"height":16}]"#).unwrap();
    fails(snerf().arg("render").arg(&asset).arg("--path").arg(&cams).arg("--out").arg(d.join("frames")).output().unwrap(), &["cams.json", "fx"]);
    fails(snerf().arg("render").arg(&asset).args(["--frames", "100000", "--size", "8x8", "--out"]).arg(d.join("frames")).output().unwrap(), &["--frames"]);
}

#[cfg(unix)]
#[test]
fn non_utf8_paths_do_not_panic() {
    use std::os::unix::ffi::OsStrExt;
    let d = tmp("utf8");
    let ds = d.join("ds");
    dataset(&ds, 6, "24x24");
    let run = d.join(std::ffi::OsStr::from_bytes(b"run-\xff\xfe"));
    let v = ok(snerf().args(["--json", "train"]).arg(&ds).arg("--out").arg(&run).args(["--steps", "2"]).output().unwrap());
    assert!(v["run"].as_str().unwrap().starts_with(d.to_str().unwrap()), "{v}");
    let v = ok(snerf().args(["--json", "eval"]).arg(&run).arg(&ds).output().unwrap());
    assert!(v["report"]["mean_psnr"].as_f64().unwrap().is_finite(), "{v}");
    let asset = d.join(std::ffi::OsStr::from_bytes(b"a\xff.snerf"));
    ok(snerf()
        .args(["--json", "bake"])
        .arg(&run)
        .arg("--data")
        .arg(&ds)
        .arg("--out")
        .arg(&asset)
        .args(["--resolution", "32", "--eval-views", "0", "--visibility-views", "4"])
        .output()
        .unwrap());
    ok(snerf().args(["--json", "inspect"]).arg(&asset).output().unwrap());
    ok(snerf().args(["--json", "render"]).arg(&asset).args(["--frames", "2", "--size", "16x16", "--out"]).arg(d.join(std::ffi::OsStr::from_bytes(b"f\xff"))).output().unwrap());
}

fn wait_for(path: &Path, secs: u64) {
    let t0 = Instant::now();
    while !path.exists() {
        assert!(t0.elapsed() < Duration::from_secs(secs), "{} did not appear", path.display());
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn ctrl_c_in_stylize_saves_the_round_and_the_same_command_continues_it() {
    let d = tmp("stylize-int");
    let ds = d.join("ds");
    dataset(&ds, 6, "16x16");
    let run = d.join("run");
    train(&ds, &run, 3);
    let srun = d.join("srun");
    let style = ds.join("test/r_000.png");
    let cmd = |json: bool| {
        let mut c = snerf();
        if json {
            c.arg("--json");
        }
        c.arg("stylize")
            .arg(&run)
            .arg("--out")
            .arg(&srun)
            .args(["--stylizer", "color", "--rounds", "1", "--steps-per-round", "300", "--consistency-frames", "0", "--style"])
            .arg(&style);
        c
    };
    let child = cmd(false).stderr(Stdio::piped()).spawn().unwrap();
    // the round's sheet is written just before its training steps start
    wait_for(&srun.join("rounds/round_1.png"), 120);
    std::thread::sleep(Duration::from_millis(700));
    assert!(Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap().success());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{stderr}");
    assert!(stderr.contains("round 1 saved at step"), "{stderr}");
    let partial: serde_json::Value = serde_json::from_slice(&bytes(&srun.join("partial/partial.json"))).unwrap();
    let done = partial["steps_done"].as_u64().unwrap();
    assert!(done > 0 && done < 300, "{partial}");
    // the same command finishes the round from there and clears the partial state
    let v = ok(cmd(true).output().unwrap());
    assert_eq!(v["state"]["rounds_done"].as_u64(), Some(1), "{v}");
    assert!(!srun.join("partial").exists());
    assert!(srun.join("checkpoint.snerfck").exists());
}

#[test]
fn serve_json_and_a_token_from_a_file_or_the_environment() {
    let d = tmp("serve");
    let ds = d.join("ds");
    dataset(&ds, 6, "16x16");
    let run = d.join("run");
    train(&ds, &run, 2);
    let assets = d.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    ok(snerf()
        .args(["--json", "bake"])
        .arg(&run)
        .arg("--out")
        .arg(assets.join("a.snerf"))
        .args(["--resolution", "32", "--eval-views", "0", "--visibility-views", "4"])
        .output()
        .unwrap());
    let token_file = d.join("token");
    std::fs::write(&token_file, "a-long-secret-token-0123456789\n").unwrap();
    let mut server = snerf()
        .args(["--json", "serve"])
        .arg(&assets)
        .args(["--listen", "127.0.0.1:0", "--state"])
        .arg(d.join("state"))
        .arg("--token-file")
        .arg(&token_file)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(server.stdout.take().unwrap()), &mut line).unwrap();
    let ready: serde_json::Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("serve --json: {e}: {line}"));
    assert!(ready["token"].is_null(), "a token from the user's file is not printed: {ready}");
    assert!(!line.contains("a-long-secret"), "{line}");
    let addr = ready["address"].as_str().unwrap();
    let pin = ready["fingerprint"].as_str().unwrap();
    let url = format!("quic://{addr}/a.snerf");
    let fetched = d.join("f1.snerf");
    ok(snerf().args(["--json", "fetch", &url, "--pin", pin, "--token-file"]).arg(&token_file).arg("--out").arg(&fetched).output().unwrap());
    assert_eq!(bytes(&fetched), bytes(&assets.join("a.snerf")));
    let fetched2 = d.join("f2.snerf");
    ok(snerf().args(["--json", "fetch", &url, "--pin", pin, "--out"]).arg(&fetched2).env("SNERF_TOKEN", "a-long-secret-token-0123456789").output().unwrap());
    assert_eq!(bytes(&fetched2), bytes(&fetched));
    fails(snerf().args(["fetch", &url, "--pin", pin, "--out"]).arg(d.join("f3")).env_remove("SNERF_TOKEN").output().unwrap(), &["--token-file", "SNERF_TOKEN"]);
    assert!(Command::new("kill").args(["-INT", &server.id().to_string()]).status().unwrap().success());
    let out = server.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("a-long-secret"), "the banner does not print a token from a file: {stderr}");
    assert!(stderr.contains("fingerprint"), "{stderr}");
}
