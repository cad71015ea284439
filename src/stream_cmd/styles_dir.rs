//! `snerf serve ASSET --styles-dir DIR --styles-run SRUN`: new style layers while serving.
//!
//! A thread polls DIR for paintings (PNG, JPEG). A new one, once its size and modification
//! time hold still for one poll (a copy in progress is not read half-written), becomes a
//! layer of the layered stylize run SRUN exactly as `snerf stylize` makes one (the first
//! layer's recorded options, this painting: `snerf_loop::run`), its colour is baked onto the
//! asset's geometry (`snerf_baker::layers::bake_colour`, the geometry read back from the
//! asset, so the styles already there are kept byte for byte), the asset is written again
//! atomically with the style added and SRUN/layers.json lists it, and every watching session
//! is told (`snerf_stream::server::Announcer`). Sessions opened afterwards read the new file.
//!
//! A painting whose style name the asset already has is not trained again; a file that cannot
//! be used is reported once, by name, until it changes; the server keeps serving either way.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::{Duration, Instant, SystemTime};

use anyhow::{bail, Context, Result};
use serde_json::json;
use snerf_asset::{LayeredAsset, StyleInfo};
use snerf_stream::server::{Announcer, Offer};
use snerf_stylize::consistency::StyleMeters;
use snerf_stylize::layers::{style_name, LayerRecord, LayersRecord};
use snerf_stylize::paintings;
use snerf_stylize::snerf_loop::{self, Progress, RoundRecord, StylizeState};
use snerf_stylize::stylizer::{self, StylizerOptions};
use snerf_trainer::checkpoint;
use snerf_trainer::run_dir::RunDir;

/// What the watcher needs, checked before the server starts.
pub struct StylesDir {
    dir: PathBuf,
    srun: PathBuf,
    asset: PathBuf,
    /// The name the server serves the asset under.
    asset_name: String,
    models: Option<PathBuf>,
    poll: Duration,
    /// The asset's style names (what is not trained again).
    styles: Vec<String>,
    /// Paintings clients asked for (`Offer`), by key.
    requests: Option<mpsc::Receiver<String>>,
}

/// The installed paintings (`painting:KEY`, `bash scripts/setup-styles.sh`), by key: what a
/// client may ask the server to train. Only these: a client never names a file.
fn installed_paintings() -> Vec<String> {
    let dir = paintings::styles_dir();
    paintings::all().filter(|p| p.pieces.iter().all(|q| dir.join(q.file).is_file())).map(|p| p.key.to_string()).collect()
}

/// A painting as last seen: its size and modification time, and what became of it.
#[derive(Clone, Copy, PartialEq)]
enum Seen {
    /// First seen at this instant; used once it holds still for a poll.
    Settling(u64, SystemTime, Instant),
    /// Added, skipped or failed (reported): nothing more until the file changes.
    Done(u64, SystemTime),
}

const PAINTING_EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "webp"];

fn say(msg: &str) {
    eprintln!("snerf serve: {msg}");
}

impl StylesDir {
    /// Check that `asset` is the multi-style bake of the layered stylize run `srun` (its first
    /// style is the run's first layer, whose field holds the geometry), and make `dir`.
    pub fn open(dir: &Path, srun: &Path, asset: &Path, models: Option<PathBuf>, poll: Duration) -> Result<StylesDir> {
        if !asset.is_file() {
            bail!("{}: --styles-dir needs one multi-style asset file to serve (the bake of --styles-run), not a directory", asset.display());
        }
        let record = LayersRecord::read(srun)?.with_context(|| {
            format!("--styles-run {}: no {} here (expected the --out of `snerf stylize` with several --style)", srun.display(), snerf_stylize::layers::RECORD)
        })?;
        let layered = LayeredAsset::read(asset)
            .with_context(|| format!("{}: --styles-dir adds styles to a multi-style asset (`snerf bake` of a layered run)", asset.display()))?;
        let first = &record.layers[0].name;
        if layered.styles[0].name != *first {
            bail!(
                "{}: its first style is {:?}, but the first layer of {} is {:?}: serve the asset `snerf bake {}` wrote",
                asset.display(),
                layered.styles[0].name,
                srun.display(),
                first,
                srun.display()
            );
        }
        let first_dir = LayersRecord::dir(srun, first);
        StylizeState::read(&first_dir)?
            .with_context(|| format!("{}: layer {first:?} has no stylize.json (its stylization has not finished)", first_dir.display()))?;
        std::fs::create_dir_all(dir).with_context(|| format!("--styles-dir {}: cannot create", dir.display()))?;
        Ok(StylesDir {
            dir: dir.to_path_buf(),
            srun: srun.to_path_buf(),
            asset: asset.to_path_buf(),
            asset_name: snerf_stream::server::asset_name(asset),
            models,
            poll,
            styles: layered.names(),
            requests: None,
        })
    }

    /// What the server offers clients to train (`ServeOptions::offer`): the installed
    /// paintings; their requests come to this watcher.
    pub fn offer(&mut self) -> Offer {
        let (tx, rx) = mpsc::channel();
        self.requests = Some(rx);
        Offer { asset: self.asset_name.clone(), paintings: installed_paintings(), requests: tx }
    }

    /// Watch on a thread of its own until the process ends.
    pub fn spawn(mut self, announcer: Announcer) -> Result<()> {
        say(&format!(
            "watching {} for new paintings (png, jpg, webp) to add as styles of {} (layers in {}); styles now: {}",
            self.dir.display(),
            self.asset_name,
            self.srun.display(),
            self.styles.join(", ")
        ));
        std::thread::Builder::new()
            .name("snerf-styles-dir".into())
            .spawn(move || {
                let mut seen = BTreeMap::new();
                let requests = self.requests.take();
                loop {
                    self.poll_once(&mut seen, &announcer);
                    // a client's request wakes the watcher at once
                    let key = match &requests {
                        Some(rx) => rx.recv_timeout(self.poll).ok(),
                        None => {
                            std::thread::sleep(self.poll);
                            None
                        }
                    };
                    for key in key.into_iter().chain(requests.iter().flat_map(|rx| rx.try_iter())) {
                        self.requested(&key, &announcer);
                    }
                }
            })
            .context("cannot start the styles-dir thread")?;
        Ok(())
    }

    /// One look at the folder; paintings that held still since the last look are handled in
    /// name order, one at a time.
    fn poll_once(&mut self, seen: &mut BTreeMap<PathBuf, Seen>, announcer: &Announcer) {
        let entries = match std::fs::read_dir(&self.dir) {
            Ok(rd) => rd,
            Err(e) => return say(&format!("--styles-dir {}: cannot read: {e}", self.dir.display())),
        };
        let mut files: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
        files.sort();
        for path in files {
            let hidden = path.file_name().is_some_and(|n| n.to_string_lossy().starts_with('.'));
            let Ok(meta) = std::fs::metadata(&path) else { continue };
            if hidden || !meta.is_file() {
                continue;
            }
            let now = (meta.len(), meta.modified().unwrap_or(SystemTime::UNIX_EPOCH));
            let first_seen = match seen.get(&path) {
                Some(Seen::Done(l, m)) if (*l, *m) == now => continue,
                Some(Seen::Settling(l, m, t)) if (*l, *m) == now => *t,
                _ => {
                    seen.insert(path.clone(), Seen::Settling(now.0, now.1, Instant::now()));
                    continue;
                }
            };
            seen.insert(path.clone(), Seen::Done(now.0, now.1));
            let ext = path.extension().map(|x| x.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
            if !PAINTING_EXTENSIONS.contains(&ext.as_str()) {
                say(&format!("{}: not a painting (png, jpg or webp): ignored", path.display()));
                continue;
            }
            let name = style_name(&path.to_string_lossy());
            if self.styles.contains(&name) {
                say(&format!("{}: {} already has the style {name:?}: not trained again", path.display(), self.asset_name));
                continue;
            }
            if let Err(e) = self.add_file(&path, &name, first_seen, announcer) {
                say(&format!("{}: cannot add it as a style: {e:#}", path.display()));
            }
        }
    }

    /// A client asked for the installed painting `key` (offered, so known).
    fn requested(&mut self, key: &str, announcer: &Announcer) {
        let spec = format!("{}{key}", paintings::STYLE_PREFIX);
        let name = style_name(&spec);
        if self.styles.contains(&name) {
            return say(&format!("{spec}: {} already has the style {name:?}: not trained again", self.asset_name));
        }
        let t0 = Instant::now();
        let r = paintings::resolve_style(Path::new(&spec)).and_then(|path| self.add(&path, spec.clone(), &name, t0, announcer));
        if let Err(e) = r {
            say(&format!("{spec}: cannot add it as a style: {e:#}"));
        }
    }

    /// `add` of a painting file from the folder (the run records its absolute path).
    fn add_file(&mut self, painting: &Path, name: &str, first_seen: Instant, announcer: &Announcer) -> Result<()> {
        let painting = std::path::absolute(painting).unwrap_or_else(|_| painting.to_path_buf());
        let spec = painting.to_str().context("not a UTF-8 name (the run records it): rename it")?.to_string();
        self.add(&painting, spec, name, first_seen, announcer)
    }

    /// Train, bake and offer the style `name` after the image `painting` (`spec`: the style
    /// as the run records it, as `--style` would give it).
    fn add(&mut self, painting: &Path, spec: String, name: &str, first_seen: Instant, announcer: &Announcer) -> Result<()> {
        let painting = painting.to_path_buf();
        // Read before any work: a file that is not an image fails here, by name.
        let style_img = stylizer::load_style_image(&painting)?;
        let mut record = LayersRecord::read(&self.srun)?.with_context(|| format!("{}: its layers record is gone", self.srun.display()))?;
        let first_dir = LayersRecord::dir(&self.srun, &record.layers[0].name);
        let first = StylizeState::read(&first_dir)?.with_context(|| format!("{}: no stylize.json", first_dir.display()))?;
        let mut opts = first.options.clone();
        opts.style = painting.clone();
        let out = LayersRecord::dir(&self.srun, name);
        say(&format!("{}: training the style {name:?} into {} ({} rounds × {} steps, {} stylizer)", painting.display(), out.display(), opts.rounds, opts.steps_per_round, opts.stylizer));
        let t0 = Instant::now();
        let sopts = StylizerOptions { strength: opts.strength, models_dir: self.models.clone(), ..StylizerOptions::default() };
        let stylizer = stylizer::from_spec(&opts.stylizer, Some(&painting), &sopts)?;
        let meters = StyleMeters::open(&sopts);
        let data = crate::args::DataOpts::default().load(&opts.data)?;
        let source = checkpoint::load(&RunDir::new(&opts.source_run).checkpoint())?;
        std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
        let mut progress = Lines::new(name);
        snerf_loop::run(&opts, &data, &source, stylizer.as_ref(), &meters, &style_img, &out, &mut progress)?;
        let train_seconds = t0.elapsed().as_secs_f64();

        let t1 = Instant::now();
        say(&format!("style {name:?}: trained in {train_seconds:.1} s; baking it onto {}", self.asset.display()));
        let (geometry_model, geometry_pool) = RunDir::new(&first_dir).load_model()?;
        let (model, pool) = RunDir::new(&out).load_model()?;
        let layered = LayeredAsset::read(&self.asset)?;
        let (asset, report) = snerf_baker::layers::bake_colour(&model, &pool, &geometry_model, &layered.layers[0])
            .with_context(|| format!("layer {name:?} was trained on another geometry than {}", self.asset.display()))?;
        drop((geometry_model, geometry_pool));
        let LayeredAsset { mut styles, mut layers } = layered;
        styles.push(StyleInfo { name: name.to_string(), source: Some(spec.clone()), swatch: snerf_asset::layers::swatch(&asset) });
        layers.push(asset);
        let bigger = LayeredAsset::new(styles, layers)?;
        bigger.write(&self.asset)?;
        // the record after the asset: a layer it lists is in the asset
        record.layers.retain(|l| l.name != name);
        record.layers.push(LayerRecord { name: name.to_string(), source: spec.clone(), seconds: Some(train_seconds) });
        record.write(&self.srun)?;
        let bake_seconds = t1.elapsed().as_secs_f64();
        self.styles = bigger.names();
        let told = announcer.styles_changed(&self.asset_name)?;
        let offered_after = first_seen.elapsed().as_secs_f64();
        say(&format!(
            "style {name:?} added to {} in {offered_after:.1} s since the painting was seen (train {train_seconds:.1} s, bake {bake_seconds:.1} s); stream it as {}.{name}",
            self.asset.display(),
            self.asset_name
        ));
        let line = json!({
            "event": "style_added",
            "asset": self.asset_name,
            "file": crate::args::pj(&self.asset),
            "style": name,
            "painting": spec,
            "train_seconds": train_seconds,
            "bake_seconds": bake_seconds,
            "bake_colour_seconds": report.seconds,
            "offered_after_seconds": offered_after,
            "styles": self.styles,
            "sessions_told": told,
        });
        use std::io::Write;
        let mut o = std::io::stdout().lock();
        let _ = writeln!(o, "{line}");
        let _ = o.flush();
        Ok(())
    }
}

/// Training progress as log lines: each phase as it starts, its progress at most every 5 s,
/// each round as it ends.
struct Lines {
    name: String,
    phase: String,
    total: u64,
    last: Instant,
}

impl Lines {
    fn new(name: &str) -> Lines {
        Lines { name: name.to_string(), phase: String::new(), total: 0, last: Instant::now() }
    }
}

impl Progress for Lines {
    fn phase(&mut self, round: usize, rounds: usize, phase: &str, total: u64) {
        self.phase = if round == 0 { phase.to_string() } else { format!("round {round}/{rounds} {phase}") };
        self.total = total;
        self.last = Instant::now();
        say(&format!("style {:?}: {} ({total})", self.name, self.phase));
    }
    fn tick(&mut self, done: u64, message: &str) {
        if self.last.elapsed() >= Duration::from_secs(5) {
            self.last = Instant::now();
            say(&format!("style {:?}: {} {done}/{} {message}", self.name, self.phase, self.total));
        }
    }
    fn round_done(&mut self, r: &RoundRecord) {
        say(&format!("style {:?}: round {} done ({:.1} s, fit {:.2} dB)", self.name, r.round, r.wall_seconds, r.fit_psnr));
    }
}
