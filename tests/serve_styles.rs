//! `snerf serve ASSET --styles-dir DIR --styles-run SRUN` on the loopback: a painting dropped
//! into DIR while the server runs is trained as a new style layer and added to the served
//! asset; a watching client is told, new sessions list it, a client holding another style
//! switches to it by colour alone and ends with the new style's bytes (SHA-256 checked), and
//! the styles already there are served byte for byte as before. A file that is not an image
//! is reported by name and the server keeps serving; a painting whose style the asset has is
//! not trained again. A client may also ask for a painting the server's listing offers (the
//! installed ones), and for nothing else.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use snerf_asset::{Asset, Recolour};
use snerf_files::ScratchDir;
use snerf_stream::plan::ServedAsset;

mod common;
use common::{ok, snerf};

/// The server, killed when the test ends however it ends.
struct Server(Child);
impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn painting(path: &Path, f: impl Fn(u32, u32) -> [u8; 3]) {
    image::RgbImage::from_fn(16, 16, |x, y| image::Rgb(f(x, y))).save(path).unwrap();
}

#[test]
fn a_painting_dropped_into_the_styles_dir_becomes_a_style_every_client_can_switch_to() {
    let d = ScratchDir::new("snerf-serve-styles", "cli").unwrap();
    // a tiny layered run and its bake, as tests/style_layers.rs makes them
    let data = d.join("data");
    ok(snerf().args(["--json", "scene", "object", "--out"]).arg(&data).args(["--views", "16", "--test-views", "2", "--size", "32x32"]).output().unwrap());
    let run = d.join("run");
    ok(snerf().args(["--json", "train"]).arg(&data).arg("--out").arg(&run).args(["--steps", "40"]).output().unwrap());
    let (warm, cold, green) = (d.join("warm.png"), d.join("cold.png"), d.join("green.png"));
    painting(&warm, |x, y| [200 + (x * 3) as u8, 90 + (y * 4) as u8, 20]);
    painting(&cold, |x, y| [20, 60 + (x * 4) as u8, 180 + (y * 3) as u8]);
    painting(&green, |x, y| [30 + (x * 2) as u8, 200 + (y * 3) as u8, 40]);
    let srun = d.join("srun");
    let no_models = d.join("no-models");
    ok(snerf()
        .args(["--json", "stylize"])
        .arg(&run)
        .arg("--out")
        .arg(&srun)
        .arg("--style")
        .arg(&warm)
        .arg("--style")
        .arg(&cold)
        .args(["--stylizer", "color", "--rounds", "1", "--steps-per-round", "5", "--consistency-frames", "0", "--models"])
        .arg(&no_models)
        .output()
        .unwrap());
    let assets = d.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let file = assets.join("scene.snerf");
    ok(snerf().args(["--json", "bake"]).arg(&srun).arg("--out").arg(&file).args(["--resolution", "32", "--eval-views", "0", "--visibility-views", "4"]).output().unwrap());

    // The folder holds, before the server starts, a painting the asset has and a file that
    // only claims to be one.
    let dir = d.join("paintings");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(&warm, dir.join("warm.png")).unwrap();
    std::fs::write(dir.join("broken.png"), b"this is not an image").unwrap();
    // The paintings the server offers clients are the installed ones: here one painting's
    // pieces, copied from where `bash scripts/setup-styles.sh` installs them (when it has).
    let installed = snerf_stylize::paintings::styles_dir();
    let offered = snerf_stylize::paintings::all().find(|p| p.pieces.iter().all(|q| installed.join(q.file).is_file()));
    let styles_home = d.join("installed-paintings");
    std::fs::create_dir_all(&styles_home).unwrap();
    for q in offered.iter().flat_map(|p| p.pieces) {
        std::fs::copy(installed.join(q.file), styles_home.join(q.file)).unwrap();
    }
    let log = d.join("serve.log");
    let mut child = snerf()
        .env("SNERF_STYLES", &styles_home)
        .args(["--json", "serve"])
        .arg(&file)
        .args(["--listen", "127.0.0.1:0", "--no-web", "--styles-poll", "0.3", "--state"])
        .arg(d.join("state"))
        .arg("--styles-dir")
        .arg(&dir)
        .arg("--styles-run")
        .arg(&srun)
        .arg("--models")
        .arg(&no_models)
        .stdout(Stdio::piped())
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let _server = Server(child);
    let (tx, lines) = mpsc::channel::<serde_json::Value>();
    std::thread::spawn(move || {
        for l in BufReader::new(stdout).lines().map_while(Result::ok) {
            let _ = tx.send(serde_json::from_str(&l).unwrap_or_else(|e| panic!("stdout line is not JSON ({e}): {l}")));
        }
    });
    let read_log = || std::fs::read_to_string(&log).unwrap();
    let ready = lines.recv_timeout(Duration::from_secs(30)).unwrap_or_else(|_| panic!("the server did not start: {}", read_log()));
    let (pin, token) = (ready["fingerprint"].as_str().unwrap().to_string(), ready["token"].as_str().unwrap().to_string());
    let url = |name: &str| format!("quic://{}/{}", ready["address"].as_str().unwrap(), name);

    // a client holding the style warm, and one watching for new styles
    let held_file = d.join("held.snerf");
    snerf_stream::fetch_blocking(&url("scene.warm"), &pin, &token, &held_file).unwrap();
    let warm_before = std::fs::read(&held_file).unwrap();
    let held_info = ServedAsset::load_style("scene.warm", &file, Some("warm")).unwrap().info();
    let mut watch = snerf_stream::watch::StyleWatch::open(&url(""), &pin, &token).unwrap();
    let names = |styles: &[snerf_asset::StyleInfo]| styles.iter().map(|s| s.name.clone()).collect::<Vec<_>>();
    assert_eq!(names(watch.listing[0].styles.as_ref().unwrap()), ["warm", "cold"]);

    // Dropped in as a real copy lands: written under a hidden name, then renamed.
    std::fs::copy(&green, dir.join(".green.png.part")).unwrap();
    std::fs::rename(dir.join(".green.png.part"), dir.join("green.png")).unwrap();
    let told = watch.next(Duration::from_secs(120)).unwrap().unwrap_or_else(|| panic!("no new style within 120 s: {}", read_log()));
    assert_eq!((told.asset.as_str(), names(&told.styles)), ("scene", vec!["warm".to_string(), "cold".into(), "green".into()]));
    let added = lines.recv_timeout(Duration::from_secs(10)).unwrap();
    assert_eq!((&added["event"], &added["style"], &added["asset"]), (&"style_added".into(), &"green".into(), &"scene".into()), "{added}");
    assert!(added["train_seconds"].as_f64().unwrap() > 0.0 && added["bake_seconds"].as_f64().unwrap() > 0.0, "{added}");
    assert_eq!(added["sessions_told"], 1, "{added}");

    // a new session lists it
    let listed = snerf_stream::list_blocking(&url(""), &pin, &token).unwrap();
    assert_eq!(names(listed[0].styles.as_ref().unwrap()), ["warm", "cold", "green"]);
    // the client holding warm switches to it by colour: the new style's bytes, SHA-256 checked
    let mut held = Asset::read(&held_file).unwrap();
    let mut recolour = Recolour::new(&held);
    let sw = snerf_stream::restyle::switch_style_blocking(&url("scene.green"), &pin, &token, &mut held, &held_info, None, &mut recolour)
        .unwrap_or_else(|e| panic!("switch to the new style: {e:#}\n{}", read_log()));
    assert_eq!(sw.info.name, "scene.green");
    let green_file = d.join("green.snerf");
    snerf_stream::fetch_blocking(&url("scene.green"), &pin, &token, &green_file).unwrap();
    let green_whole = std::fs::read(&green_file).unwrap();
    assert!(held.to_bytes() == green_whole, "the switched asset is scene.green byte for byte");
    assert!(green_whole != warm_before);
    assert!(sw.bytes * 4 < green_whole.len() as u64 * 3, "a switch sends the colour part, {} bytes of {}", sw.bytes, green_whole.len());
    // the styles already there are as they were
    snerf_stream::fetch_blocking(&url("scene.warm"), &pin, &token, &held_file).unwrap();
    assert!(std::fs::read(&held_file).unwrap() == warm_before, "adding a style changed the style warm");

    // the log names the broken file and the painting not trained again; the run lists the new
    // layer once, after the two it had
    let text = read_log();
    assert!(text.lines().any(|l| l.contains("broken.png") && l.contains("not a PNG")), "{text}");
    assert!(text.lines().any(|l| l.contains("warm.png") && l.contains("not trained again")), "{text}");
    assert!(text.contains("style \"green\": round 1 done"), "training progress: {text}");
    let record: serde_json::Value = serde_json::from_slice(&std::fs::read(srun.join("layers.json")).unwrap()).unwrap();
    let layers: Vec<&str> = record["layers"].as_array().unwrap().iter().map(|l| l["name"].as_str().unwrap()).collect();
    assert_eq!(layers, ["warm", "cold", "green"]);
    // the file on disk is the three-style asset
    let layered = snerf_asset::LayeredAsset::read(&file).unwrap();
    assert_eq!(layered.names(), ["warm", "cold", "green"]);

    // A painting chosen from the server's list: only what it offers is trained.
    let Some(p) = offered else {
        assert_eq!(listed[0].paintings, Some(vec![]), "no painting installed, none offered");
        eprintln!("no painting installed in {} (bash scripts/setup-styles.sh): the request of one is not tested", installed.display());
        return;
    };
    assert_eq!(listed[0].paintings, Some(vec![p.key.to_string()]));
    assert_eq!(watch.add_style("scene", p.key).unwrap(), p.key);
    let told = watch.next(Duration::from_secs(120)).unwrap().unwrap_or_else(|| panic!("no new style within 120 s: {}", read_log()));
    assert_eq!(names(&told.styles), ["warm", "cold", "green", p.key]);
    let added = lines.recv_timeout(Duration::from_secs(10)).unwrap();
    assert_eq!((&added["style"], &added["painting"]), (&p.key.into(), &format!("painting:{}", p.key).into()), "{added}");
    let listed = snerf_stream::list_blocking(&url(""), &pin, &token).unwrap();
    assert_eq!(listed[0].paintings, Some(vec![]), "a painting the asset has is offered no more");
    let mut held = Asset::read(&held_file).unwrap();
    snerf_stream::restyle::switch_style_blocking(&url(&format!("scene.{}", p.key)), &pin, &token, &mut held, &held_info, None, &mut recolour).unwrap();
    // asking again, or for anything not offered, is refused by name; nothing is trained
    for bad in [p.key, "vangogh-not-a-key"] {
        let mut w = snerf_stream::watch::StyleWatch::open(&url(""), &pin, &token).unwrap();
        let e = format!("{:#}", w.add_style("scene", bad).unwrap_err());
        assert!(e.contains("not offered") && e.contains(bad), "{e}");
    }
    assert_eq!(snerf_asset::LayeredAsset::read(&file).unwrap().names().len(), 4);
}
