//! The SNeRF loop on a tiny trained field, with the weight-free `color` stylizer (so it runs
//! without model files): rounds are recorded and resumable, appearance-only keeps geometry
//! bit-for-bit, and the stylized field is more consistent across views than stylizing each
//! novel view on its own.

use std::path::{Path, PathBuf};

use snerf_data::{load, LoadOptions};
use snerf_files::ScratchDir;
use snerf_stylize::colour_offsets::ColourOffsets;
use snerf_stylize::consistency::{PathGeometry, StyleMeters, STYLE_RING};
use snerf_stylize::snerf_loop::{self, Quiet, StylizeOptions};
use snerf_stylize::stylizer::{self, Image, StylizerOptions};
use snerf_trainer::checkpoint;
use snerf_trainer::train::{TrainConfig, Trainer};

/// This test's directory: removed when it passes, kept (and named) when it fails.
fn tmp(name: &str) -> ScratchDir {
    ScratchDir::new("snerf-sloop", name).unwrap()
}

/// A 48×48 object dataset, a field trained on it for a few hundred steps, saved as a run.
fn trained_run(dir: &Path) -> (snerf_data::Dataset, PathBuf) {
    let mut spec = snerf_scene::SceneSpec::default_for(snerf_scene::Source::Object);
    spec.train_views = 24;
    spec.test_views = 4;
    spec.width = 48;
    spec.height = 48;
    spec.supersample = 2;
    let data_dir = dir.join("data");
    snerf_scene::write_dataset(&spec, &data_dir, &|_, _| {}).unwrap();
    let data = load(&data_dir, &LoadOptions::default()).unwrap();
    let mut t = Trainer::new(&data, TrainConfig::for_dataset(&data)).unwrap();
    for s in 0..250 {
        t.step(s as f64 / 250.0);
    }
    let run = dir.join("run");
    std::fs::create_dir_all(&run).unwrap();
    checkpoint::save(&t, &run.join(checkpoint::FILE_NAME)).unwrap();
    (data, run)
}

/// A style picture: warm diagonal stripes.
fn style_png(dir: &Path) -> PathBuf {
    let img = image::RgbImage::from_fn(64, 64, |x, y| {
        if (x + y) / 8 % 2 == 0 {
            image::Rgb([230, 120, 30])
        } else {
            image::Rgb([90, 20, 110])
        }
    });
    let p = dir.join("style.png");
    img.save(&p).unwrap();
    p
}

/// What every loop test starts from: a fresh directory, a trained run on a small object
/// dataset, a style picture and its loaded forms.
struct Fixture {
    dir: ScratchDir,
    data: snerf_data::Dataset,
    run: PathBuf,
    style: PathBuf,
    source: checkpoint::Checkpoint,
    style_img: Image,
}

fn fixture(name: &str) -> Fixture {
    let dir = tmp(name);
    let (data, run) = trained_run(&dir);
    let style = style_png(&dir);
    let source = checkpoint::load(&run.join(checkpoint::FILE_NAME)).unwrap();
    let style_img = stylizer::load_style_image(&style).unwrap();
    Fixture { dir, data, run, style, source, style_img }
}

fn options(run: &Path, data: &Path, style: &Path, rounds: usize, appearance_only: bool) -> StylizeOptions {
    StylizeOptions {
        source_run: run.to_path_buf(),
        data: data.to_path_buf(),
        style: style.to_path_buf(),
        stylizer: "color".into(),
        rounds,
        steps_per_round: 40,
        views: 12,
        appearance_only,
        consistency_frames: 10,
        ..StylizeOptions::default()
    }
}

/// `o` with `steps` a round and no per-round measurement.
fn fixed_content(mut o: StylizeOptions, steps: u64) -> StylizeOptions {
    o.steps_per_round = steps;
    o.consistency_frames = 0;
    o.content = snerf_loop::Content::Realistic;
    o
}

#[test]
fn rounds_resume_and_appearance_only_freezes_geometry() {
    let Fixture { dir, data, run, style, source, style_img } = fixture("loop");
    let st = stylizer::from_spec("color", Some(&style), &StylizerOptions::default()).unwrap();

    // one round, then ask for two: the second run resumes after round 1 (more rounds extend
    // a run; other changed options are refused)
    let out = dir.join("srun");
    let o1 = options(&run, &data.root, &style, 1, false);
    let s1 = snerf_loop::run(&o1, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(s1.rounds_done, 1);
    let mut other = o1.clone();
    other.steps_per_round = 41;
    assert!(snerf_loop::run(&other, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).is_err());
    let o2 = options(&run, &data.root, &style, 2, false);
    let s = snerf_loop::run(&o2, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(s.rounds_done, 2);
    assert_eq!(s.records.len(), 2);
    assert!(s.records.iter().all(|r| r.short_range.is_some_and(|x| x.is_finite())), "{:?}", s.records);
    assert!(s.records.iter().all(|r| r.style_swd.is_some_and(|x| x.total.is_finite() && x.total > 0.0)), "{:?}", s.records);
    assert!(s.records.iter().all(|r| r.fused_fraction.is_some_and(|f| f > 0.3)), "{:?}", s.records);
    assert!(out.join("rounds/round_2.png").exists());
    // a finished run re-run with the same options does nothing more
    let again = snerf_loop::run(&o2, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(again.records.len(), 2);
    let geo = checkpoint::load(&out.join(checkpoint::FILE_NAME)).unwrap();
    let plane_end = source.model.field.layout.plane_end;
    let moved = source.model.field.params[..plane_end].iter().zip(&geo.model.field.params[..plane_end]).filter(|(a, b)| a != b).count();
    assert!(moved > 0, "stylizing geometry (the default) must move the density planes");
    // the stylizing trainer does not smooth the planes (the realistic one did) and draws its
    // rays across the pixels' squares, and says so in the checkpoint
    assert!(source.cfg.tv > 0.0);
    assert_eq!((geo.cfg.tv, geo.cfg.area_rays), (0.0, true));
    // every round measured on the loop's own path, and the record says which frames
    assert!(s.records.iter().all(|r| r.measured_on.as_deref().is_some_and(|m| m.contains("the loop's path: 10 frames"))), "{:?}", s.records);
    let v = source.model.field.layout.view;
    assert!(source.model.field.params[v.w3..v.end].iter().any(|&w| w != 0.0), "the realistic field learnt no view-dependent colour");

    // appearance only: planes, shared layer and the density output stay bit-identical
    let out = dir.join("appearance");
    let oa = options(&run, &data.root, &style, 1, true);
    snerf_loop::run(&oa, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    let app = checkpoint::load(&out.join(checkpoint::FILE_NAME)).unwrap();
    // a diffuse stylized field: the view MLP's output layer is zero and stayed zero
    assert!(app.model.field.params[v.w3..v.end].iter().all(|&w| w == 0.0), "a diffuse stylized field kept a view-dependent residual");
    let l = &source.model.field.layout;
    let (a, b) = (&source.model.field.params, &app.model.field.params);
    assert!(a[..l.w2 + l.hidden] == b[..l.w2 + l.hidden], "appearance-only moved the geometry");
    assert_eq!(a[l.b2], b[l.b2], "appearance-only moved the density bias");
    assert!(a[l.w2 + l.hidden..l.b2] != b[l.w2 + l.hidden..l.b2], "appearance-only did not learn colour");
    // colour learnt through a head of its own, started from the shared layer
    let head = app.model.field.layout.colour.expect("an appearance-only field has a colour head");
    assert_eq!(head.w1, l.total, "the colour head comes after every parameter the source had");
    assert!(b[head.w1..] != a[l.w1..l.w2], "the colour head did not learn");
}

#[test]
fn stylized_field_is_more_consistent_than_per_frame_stylization() {
    let Fixture { dir, data, run, style, source, style_img } = fixture("consistency");
    let st = stylizer::from_spec("color", Some(&style), &StylizerOptions::default()).unwrap();
    let out = dir.join("srun");
    let o = options(&run, &data.root, &style, 2, false);
    snerf_loop::run(&o, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    let stylized = checkpoint::load(&out.join(checkpoint::FILE_NAME)).unwrap();
    let pool = snerf_trainer::render::WorkspacePool::new(source.model.field.params.len());
    let path = PathGeometry::new(&source.model, &pool, &data, 12).unwrap();
    assert!(path.coverage() > 0.05, "coverage {}", path.coverage());
    // the realistic field warped onto itself is nearly consistent (sanity of the warp)
    let realistic_err = path.warp_error(&path.realistic, 1);
    // frames that flicker independently (noise per frame) are not
    let mut rng = snerf_trainer::field::Rng::new(7);
    let flicker: Vec<Image> = path
        .realistic
        .iter()
        .map(|f| Image { width: f.width, height: f.height, data: f.data.iter().map(|v| v + (rng.uniform() - 0.5) * 0.4).collect() })
        .collect();
    let flicker_err = path.warp_error(&flicker, 1);
    let snerf = path.render(&stylized.model, &pool);
    let sn = path.warp_error(&snerf, 1);
    let sn_long = path.warp_error(&snerf, 7);
    eprintln!("short-range: realistic {realistic_err:.5}, flickering {flicker_err:.5}, SNeRF {sn:.5} (long {sn_long:.5})");
    assert!(realistic_err.is_finite() && realistic_err < 0.01, "warp of the realistic frames: {realistic_err}");
    assert!(flicker_err > 3.0 * realistic_err, "the warp error does not see flicker: {flicker_err} vs {realistic_err}");
    // A field renders consistent views whatever it learned: as consistent as the realistic
    // one, give or take. (The per-frame baseline needs a neural stylizer to be interesting:
    // `color` is one global colour map per frame and nearly consistent already; the
    // comparison with `arbitrary` and presets is `snerf consistency`, in BENCH.md.)
    assert!(sn.is_finite() && sn < 3.0 * realistic_err.max(1e-4) && sn < flicker_err, "SNeRF {sn}");
    assert!(sn_long.is_finite());

    // The style distances pool the ring around the whole orbit, not the path's arc: the
    // ring's camera centres surround the orbit's centre (the 12-frame path spans 55° and
    // lies to one side of it), and the style score reads the ring's frames alone.
    assert_eq!(path.cams.len(), 12 + STYLE_RING);
    let centre = |cams: &[[[f32; 4]; 3]]| [0, 1, 2].map(|c| cams.iter().map(|m| m[c][3]).sum::<f32>() / cams.len() as f32);
    let orbit_centre = centre(&snerf_trainer::camera_path::orbit(&source.model.space, &data.train, 72));
    let radius = { let m = path.cams[0]; ((0..3).map(|c| (m[c][3] - orbit_centre[c]).powi(2)).sum::<f32>()).sqrt() };
    let off = |cams: &[[[f32; 4]; 3]]| { let m = centre(cams); ((0..3).map(|c| (m[c] - orbit_centre[c]).powi(2)).sum::<f32>()).sqrt() / radius };
    assert!(off(&path.cams[12..]) < 0.05, "ring centroid {:.3} radii off the orbit's centre", off(&path.cams[12..]));
    assert!(off(&path.cams[..12]) > 0.5, "path centroid {:.3} radii off", off(&path.cams[..12]));
    let reference = path.style_reference(&style_img);
    let base = path.style_score(&snerf, &reference);
    let mut other_path = snerf.clone();
    for f in &mut other_path[..12] {
        f.data.iter_mut().for_each(|v| *v = 1.0 - *v);
    }
    assert_eq!(path.style_score(&other_path, &reference), base, "the path's frames changed the style score");
    let mut other_ring = snerf.clone();
    for f in &mut other_ring[12..] {
        f.data.iter_mut().for_each(|v| *v = 1.0 - *v);
    }
    assert_ne!(path.style_score(&other_ring, &reference), base, "the ring's frames did not count");
}

/// Counts the images it is given and returns them brighter by a fixed amount (a stand-in for
/// a feed-forward stylizer: it changes whatever it gets, including its own earlier output).
struct Counting {
    calls: std::sync::atomic::AtomicUsize,
    /// Mean colour of every input, in call order.
    means: std::sync::Mutex<Vec<f64>>,
}

impl stylizer::Stylizer for Counting {
    fn name(&self) -> String {
        "counting".into()
    }
    fn stylize(&self, content: &Image) -> anyhow::Result<Image> {
        self.calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        let mean = content.data.iter().map(|&v| v as f64).sum::<f64>() / content.data.len() as f64;
        self.means.lock().unwrap().push(mean);
        Ok(Image { width: content.width, height: content.height, data: content.data.iter().map(|v| (v + 0.2).min(1.0)).collect() })
    }
}

/// `Content::Realistic` stylizes the realistic renders once, whatever the number of rounds;
/// `Content::Render` stylizes each round's render, so it sees the field drift.
#[test]
fn realistic_content_is_stylized_once_and_render_content_every_round() {
    let Fixture { dir, data, run, style, source, style_img } = fixture("content");
    let mut runs = Vec::new();
    for content in [snerf_loop::Content::Realistic, snerf_loop::Content::Render] {
        let st = Counting { calls: Default::default(), means: Default::default() };
        let mut o = options(&run, &data.root, &style, 3, false);
        o.steps_per_round = 20;
        o.consistency_frames = 0;
        o.content = content;
        let s = snerf_loop::run(&o, &data, &source, &st, &StyleMeters::default(), &style_img, &dir.join(format!("{content:?}")), &mut Quiet).unwrap();
        assert_eq!(s.rounds_done, 3);
        let steps: Vec<f32> = s.records.iter().map(|r| r.target_step.unwrap()).collect();
        let expected = if content == snerf_loop::Content::Render { vec![1.0, 0.25, 1.0 / 9.0] } else { vec![1.0, 0.5, 1.0 / 3.0] };
        assert_eq!(steps, expected, "{content:?}");
        // the record says how many views the stylizer painted in each round
        let painted: Vec<usize> = s.records.iter().map(|r| r.stylized_views.unwrap()).collect();
        let expected = if content == snerf_loop::Content::Render { vec![12; 3] } else { vec![12, 0, 0] };
        assert_eq!(painted, expected, "{content:?}");
        runs.push((st.calls.into_inner(), st.means.into_inner().unwrap()));
    }
    let views = 12;
    let (realistic_calls, _) = &runs[0];
    assert_eq!(*realistic_calls, views, "realistic content: one stylization per view for the whole run");
    let (render_calls, means) = &runs[1];
    assert_eq!(*render_calls, 3 * views, "render content: one stylization per view and round");
    // the brightening stylizer pulled the field brighter, so round 3 stylized brighter renders
    let first: f64 = means[..views].iter().sum::<f64>() / views as f64;
    let last: f64 = means[2 * views..].iter().sum::<f64>() / views as f64;
    assert!(last > first + 0.01, "render content did not see the field change: round 1 mean {first:.4}, round 3 {last:.4}");
}

/// Paints its whole input one flat grey, a different one each round (`levels[round]`, the
/// round counted from its calls): a stylizer with no fixed point at all.
struct Flat {
    calls: std::sync::atomic::AtomicUsize,
    views: usize,
    levels: Vec<f32>,
}

impl stylizer::Stylizer for Flat {
    fn name(&self) -> String {
        "flat".into()
    }
    fn stylize(&self, content: &Image) -> anyhow::Result<Image> {
        let round = self.calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst) / self.views;
        let v = self.levels[round.min(self.levels.len() - 1)];
        Ok(Image::filled(content.width, content.height, [v; 3]))
    }
}

/// The paper's loop (the default) moves its targets toward each round's stylization by
/// 1/t²: with a stylizer that paints 0.2, then 0.8, then 0.5 (no fixed point), the painted
/// pixels' targets are 0.2, 0.2 + 0.6/4 = 0.35 and 0.35 + 0.15/9 ≈ 0.367 (a running mean,
/// steps 1/t, would give 0.2, 0.5, 0.5).
#[test]
fn the_papers_loop_steps_its_targets_by_one_over_t_squared() {
    let Fixture { dir, data, run, style, source, style_img } = fixture("one_over_t2");
    let out = dir.join("srun");
    let mut o = options(&run, &data.root, &style, 3, false);
    assert_eq!(o.content, snerf_loop::Content::Render);
    (o.steps_per_round, o.consistency_frames, o.fuse_views) = (10, 0, 0);
    let st = Flat { calls: Default::default(), views: 12, levels: vec![0.2, 0.8, 0.5] };
    snerf_loop::run(&o, &data, &source, &st, &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(st.calls.into_inner(), 36, "the stylizer runs on every view every round");
    let read = |round: usize, i: usize| stylizer::image_from_png(&out.join(format!("targets/round_{round}/view_{i:03}.png"))).unwrap().data;
    let q = |v: f32| (v * 255.0).round() / 255.0;
    let (mut values, mut checked) = (0, 0);
    for i in 0..12 {
        let (r2, r3) = (read(2, i), read(3, i));
        // the pixels the stylizer painted: the object's box; outside it the render stays
        for (p, &t2) in r2.iter().enumerate() {
            values += 1;
            if (t2 - q(0.35)).abs() > 1.5 / 255.0 {
                continue;
            }
            checked += 1;
            assert!((r3[p] - q(q(0.35) + (0.5 - q(0.35)) / 9.0)).abs() <= 1.0 / 255.0, "view {i} value {p}: round 3 {} after {t2}", r3[p]);
        }
    }
    assert!(checked * 10 > values, "only {checked} of {values} target values at round 2 are 0.2 + (0.8 - 0.2)/4");
}

/// `Targets::Consensus`: each round fuses the last round's fused targets; they are saved per
/// round, so a resumed run continues the iteration without stylizing again.
#[test]
fn consensus_targets_carry_over_rounds_and_resumes() {
    let Fixture { dir, data, run, style, source, style_img } = fixture("consensus");
    let out = dir.join("srun");
    // round 1 gives each point its nearest painter, later rounds the median, keeping the
    // first fusion's palette, saved with it
    let mut o = fixed_content(options(&run, &data.root, &style, 1, false), 20);
    let st = Counting { calls: Default::default(), means: Default::default() };
    snerf_loop::run(&o, &data, &source, &st, &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(st.calls.into_inner(), 12, "round 1 stylizes every view once");
    let views_in = |round: usize| std::fs::read_dir(out.join(format!("consensus/round_{round}"))).map(|d| d.count()).unwrap_or(0);
    assert_eq!(views_in(1), 12);
    assert!(out.join("consensus/palette.json").exists(), "the palette the rounds keep is saved with round 1");
    // Resume for three rounds in a new process: the consensus of round 1 is read back, and
    // its palette (not made again: without the file the run stops and names it).
    o.rounds = 3;
    let pal = out.join("consensus/palette.json");
    let saved = std::fs::read(&pal).unwrap();
    std::fs::remove_file(&pal).unwrap();
    let e = snerf_loop::run(&o, &data, &source, &Counting { calls: Default::default(), means: Default::default() }, &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap_err();
    assert!(format!("{e:#}").contains("palette.json: cannot read"), "{e:#}");
    std::fs::write(&pal, &saved).unwrap();
    let st = Counting { calls: Default::default(), means: Default::default() };
    let s = snerf_loop::run(&o, &data, &source, &st, &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(s.rounds_done, 3);
    assert_eq!(st.calls.into_inner(), 0, "a resumed consensus run must not stylize again");
    assert_eq!((views_in(1), views_in(2), views_in(3)), (0, 12, 12), "rounds kept: the last two");
    // An uninterrupted run keeps the same palette (round 1's fusion does not depend on how
    // many rounds follow).
    let whole = dir.join("whole");
    snerf_loop::run(&o, &data, &source, &Counting { calls: Default::default(), means: Default::default() }, &StyleMeters::default(), &style_img, &whole, &mut Quiet).unwrap();
    assert!(std::fs::read(whole.join("consensus/palette.json")).unwrap() == saved, "round 1's palette differs between runs");
    // Without saved consensus (deleted) the resumed run falls back to stylizing once.
    std::fs::remove_dir_all(out.join("consensus")).unwrap();
    o.rounds = 4;
    let st = Counting { calls: Default::default(), means: Default::default() };
    snerf_loop::run(&o, &data, &source, &st, &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(st.calls.into_inner(), 12);
}

/// Round t's target is the running mean of the rounds' fused stylizations, stepped from the
/// previous round's target, never from the field's render: with the same stylizations every
/// round (realistic content, no fusion) every round's target is the stylization itself,
/// whatever the field rendered, also across a resume (the last round's targets are read back).
#[test]
fn targets_are_the_running_mean_across_resumes() {
    let Fixture { dir, data, run, style, source, style_img } = fixture("running_mean");
    let st = stylizer::from_spec("color", Some(&style), &StylizerOptions::default()).unwrap();
    let out = dir.join("srun");
    let mut o = fixed_content(options(&run, &data.root, &style, 2, false), 10);
    o.fuse_views = 0;
    snerf_loop::run(&o, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    let read = |round: usize| -> Vec<Vec<f32>> {
        (0..12).map(|i| stylizer::image_from_png(&out.join(format!("targets/round_{round}/view_{i:03}.png"))).unwrap().data).collect()
    };
    let (t1, t2) = (read(1), read(2));
    assert_eq!(t1, t2, "round 2's target moved away from the (unchanged) stylization");
    // resumed in a new process for a third round: steps from round 2's saved targets
    o.rounds = 3;
    let s = snerf_loop::run(&o, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(s.rounds_done, 3);
    assert_eq!(read(3), t2);
    assert!(!out.join("targets/round_1").exists(), "rounds kept: the last two");
}

/// The same training twice gives the same field, bit for bit, however the threads share the
/// work: each ray chunk adds its gradients into a fixed workspace and the workspaces are
/// added in a fixed order. Before, the thread that ran a chunk chose the buffer, and two runs
/// of one `snerf stylize` command ended rounds apart on the convergence bar (docs/stylize-notebook.md §5k).
#[test]
fn training_is_bit_reproducible_whatever_the_threads_do() {
    let threads = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap();
    let dir = tmp("repro");
    let field = |name: &str| {
        threads.install(|| {
            let (_, run) = trained_run(&dir.join(name));
            checkpoint::load(&run.join(checkpoint::FILE_NAME)).unwrap().model.field.params
        })
    };
    let (a, b) = (field("a"), field("b"));
    let differ = a.iter().zip(&b).filter(|(x, y)| x.to_bits() != y.to_bits()).count();
    assert_eq!(differ, 0, "{differ} of {} parameters differ between two identical trainings", a.len());
}

/// `--seed` changes the rays the rounds train on, and only that: the same seed trains the
/// same field to the bit, another seed another field, and the run records the seed it used.
#[test]
fn a_seed_of_its_own_changes_the_rays_and_is_recorded() {
    let Fixture { dir, data, run, style, source, style_img } = fixture("seed");
    let st = stylizer::from_spec("color", Some(&style), &StylizerOptions::default()).unwrap();
    let field = |name: &str, seed: Option<u64>| {
        let o = StylizeOptions { seed, ..fixed_content(options(&run, &data.root, &style, 1, false), 30) };
        let out = dir.join(name);
        let s = snerf_loop::run(&o, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
        assert_eq!(s.options.seed, seed);
        let ck = checkpoint::load(&out.join(checkpoint::FILE_NAME)).unwrap();
        assert_eq!(ck.cfg.seed, seed.unwrap_or(source.cfg.seed), "the checkpoint trains on with the seed it used");
        ck.model.field.params
    };
    let (own, seven, seven_again) = (field("own", None), field("seven", Some(7)), field("seven-again", Some(7)));
    assert_ne!(source.cfg.seed, 7);
    assert!(seven == seven_again, "one seed, two fields");
    assert!(own != seven, "another seed trained the same field");
}

/// The colour offsets: recorded within round 1 (halfway, in a run of one round) and added to
/// at round 2's start and within it; the targets kept for the next round's step are the
/// fused ones, not the ones moved by the offsets.
#[test]
fn colour_offsets_are_calibrated_and_resume() {
    let Fixture { dir, data, run, style, source, style_img } = fixture("offsets");
    let st = stylizer::from_spec("color", Some(&style), &StylizerOptions::default()).unwrap();
    let mut o = fixed_content(options(&run, &data.root, &style, 1, false), 20);
    let out = dir.join("joint");
    snerf_loop::run(&o, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(o.calibration_interval(), 10);
    let first = ColourOffsets::load(&out).unwrap().expect("halfway through round 1 the run calibrates");
    let kept: Vec<Vec<f32>> = (0..12).map(|i| stylizer::image_from_png(&out.join(format!("targets/round_1/view_{i:03}.png"))).unwrap().data).collect();
    let fused: Vec<Vec<f32>> = (0..12).map(|i| stylizer::image_from_png(&out.join(format!("consensus/round_1/view_{i:03}.png"))).unwrap().data).collect();
    assert_eq!(kept, fused, "round 1's kept targets are the fused stylizations, whatever the field trained on");
    o.rounds = 2;
    snerf_loop::run(&o, &data, &source, st.as_ref(), &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    let second = ColourOffsets::load(&out).unwrap().unwrap();
    assert_ne!(first, second, "round 2 adds the shortfall of the field it starts from");
}

/// Paints nothing for its first `clean` calls (the content as it is), then per-pixel noise: a
/// round that trains on it is sure to end farther from the style than one that did not.
struct NoisyAfter {
    clean: usize,
    calls: std::sync::atomic::AtomicUsize,
}

impl stylizer::Stylizer for NoisyAfter {
    fn name(&self) -> String {
        "noisy-after".into()
    }
    fn stylize(&self, content: &Image) -> anyhow::Result<Image> {
        let call = self.calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        if call < self.clean {
            return Ok(content.clone());
        }
        let mut rng = snerf_trainer::field::Rng::new(1000 + call as u64);
        Ok(Image { width: content.width, height: content.height, data: content.data.iter().map(|_| rng.uniform()).collect() })
    }
}

/// Every round's field is the run's, and its record holds what that field measured: rounds
/// that trained on noise are not set aside, and they measure farther from the style than
/// round 1 (no record carries another round's scores).
#[test]
fn every_round_is_kept_and_recorded_as_measured() {
    let Fixture { dir, data, run, style, source, style_img } = fixture("every");
    let views = 12;
    let mut o = options(&run, &data.root, &style, 1, false);
    o.content = snerf_loop::Content::Render;
    o.fuse_views = 0;
    let st = NoisyAfter { clean: views, calls: Default::default() };
    let out = dir.join("srun");
    snerf_loop::run(&o, &data, &source, &st, &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    let round1 = std::fs::read(out.join(checkpoint::FILE_NAME)).unwrap();
    o.rounds = 3;
    let s = snerf_loop::run(&o, &data, &source, &st, &StyleMeters::default(), &style_img, &out, &mut Quiet).unwrap();
    assert_eq!(s.rounds_done, 3);
    let style = |k: usize| s.records[k].style_swd.unwrap().total;
    assert!(style(1) > style(0) && style(2) > style(0), "{:?}", s.records);
    assert_ne!(s.records[1].short_range, s.records[0].short_range);
    assert!(std::fs::read(out.join(checkpoint::FILE_NAME)).unwrap() != round1, "the last round's field is the run's");
    let json = std::fs::read_to_string(snerf_loop::state_path(&out)).unwrap();
    assert!(!json.contains("discarded"), "{json}");
}

/// `snerf consistency`'s evaluation path shares no camera with the loop's own path and ring:
/// another elevation and radius.
#[test]
fn the_evaluation_path_shares_no_frame_with_the_loop() {
    let Fixture { data, source, .. } = fixture("eval_path");
    let pool = snerf_trainer::render::WorkspacePool::new(source.model.field.params.len());
    let own = PathGeometry::new(&source.model, &pool, &data, 16).unwrap();
    let eval = PathGeometry::evaluation(&source.model, &pool, &data, 24).unwrap();
    assert_eq!((own.cams.len(), eval.cams.len()), (16 + STYLE_RING, 24 + STYLE_RING));
    let centre = |m: &[[f32; 4]; 3]| [m[0][3], m[1][3], m[2][3]];
    let dist = |a: [f32; 3], b: [f32; 3]| ((0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f32>()).sqrt();
    let radius = dist(centre(&own.cams[0]), [0.0; 3]).max(1e-3);
    for e in &eval.cams {
        let nearest = own.cams.iter().map(|o| dist(centre(o), centre(e))).fold(f32::INFINITY, f32::min);
        assert!(nearest > 0.05 * radius, "an evaluation camera {:.4} from one of the loop's", nearest);
    }
    assert!(eval.description.contains("no frame shared"), "{}", eval.description);
    assert!(eval.coverage() > 0.05, "the evaluation path sees the object: {}", eval.coverage());
}
