//! The interactive window (`snerf view`): winit events -> camera controls / playback ->
//! `GpuRenderer` marches into its float buffer -> `present.wgsl` copies it to the swapchain.
//! Surface problems are handled per frame (Outdated/Lost: reconfigure or recreate,
//! Timeout/Occluded: skip), a lost device is recreated once, closing the window at any
//! point ends the loop cleanly; nothing here panics on a bad environment.

use anyhow::{anyhow, bail, Context, Result};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, ModifiersState, PhysicalKey};
use winit::window::{Window, WindowId};

use crate::bench::median;
use crate::camera::{camera_from_c2w, load_poses, stereo_pair, Controller, PoseSample};
use crate::gpu::{
    new_instance, read_buffer, DeviceLostError, GpuContext, GpuOptions, GpuRenderer, View,
    PRESENT_WGSL,
};
use snerf_asset::{Asset, ViewMlp};

/// What an `AssetSource` hands the viewer.
pub enum AssetUpdate {
    /// A whole asset (possibly partial: blocks not present and grids not arrived render
    /// empty); replaces whatever the viewer holds.
    Whole(Box<Asset>),
    /// Blocks of the asset the viewer holds arrived or changed: (atlas index, bytes).
    Blocks(Vec<(u32, Vec<u8>)>),
    /// One keyframe's indirection grid arrived.
    Grid { frame: u32, entries: Vec<u32> },
    /// The view MLP arrived.
    Mlp(ViewMlp),
}

/// What applying an update changed, so a GPU copy of the asset can follow.
#[derive(Debug, PartialEq)]
pub enum Applied {
    /// The asset was replaced.
    Whole,
    /// These atlas blocks were written.
    Blocks(Vec<u32>),
    /// A keyframe grid was written.
    Grid,
    /// The view MLP was replaced.
    Mlp,
    /// Nothing: a part with no asset to go into, or one that does not fit the asset.
    Nothing,
}

impl AssetUpdate {
    /// Apply the update to the asset a viewer holds (`None` before the first `Whole`): the
    /// one place that decides what a streamed part does to the CPU copy, shared by the
    /// window and any headless client.
    pub fn apply(self, held: &mut Option<Asset>) -> Applied {
        match (self, held.as_mut()) {
            (AssetUpdate::Whole(a), _) => {
                *held = Some(*a);
                Applied::Whole
            }
            (part, Some(asset)) => part.apply_part(asset),
            (_, None) => Applied::Nothing,
        }
    }

    /// Apply a part (blocks, a grid, the MLP) to `asset`. A part that does not fit it (a
    /// block of the wrong size or index, a grid of the wrong size or pointing past the
    /// atlas) is left out and said on stderr: a misbehaving server must not crash the viewer.
    pub fn apply_part(self, asset: &mut Asset) -> Applied {
        match self {
            AssetUpdate::Whole(a) => {
                *asset = *a;
                Applied::Whole
            }
            AssetUpdate::Blocks(blocks) => {
                let bb = asset.block_bytes();
                let mut idx = Vec::with_capacity(blocks.len());
                for (i, bytes) in blocks {
                    let i_us = i as usize;
                    if bytes.len() != bb || i_us >= asset.present.len() {
                        eprintln!("snerf view: ignoring block {} ({} bytes)", i, bytes.len());
                        continue;
                    }
                    asset.atlas[i_us * bb..(i_us + 1) * bb].copy_from_slice(&bytes);
                    asset.present[i_us] = true;
                    idx.push(i);
                }
                Applied::Blocks(idx)
            }
            AssetUpdate::Grid { frame, entries } => {
                let g3 = asset.grid_dim().pow(3);
                let n = asset.header.atlas_blocks;
                let motion_ok = asset.header.motion_ref.is_some_and(|r| r != frame);
                let bad = |e: u32| e != snerf_asset::EMPTY && e >= n && !(motion_ok && snerf_asset::motion::is_motion(e));
                if entries.len() != g3 || frame as usize >= asset.grids.len() || entries.iter().any(|&e| bad(e))
                {
                    eprintln!("snerf view: ignoring a bad grid for frame {}", frame);
                    return Applied::Nothing;
                }
                asset.grids[frame as usize] = entries;
                Applied::Grid
            }
            AssetUpdate::Mlp(m) => {
                asset.mlp = m;
                Applied::Mlp
            }
        }
    }
}

/// Where the window's asset comes from: a file (everything at once) or a stream.
pub trait AssetSource {
    /// Called every frame until it returns None; must not block.
    fn poll(&mut self) -> Option<AssetUpdate>;
    /// The viewer's eye position and view direction (world space), every frame, so a
    /// streaming source can send the blocks this view needs first.
    fn set_pose(&mut self, _eye: [f32; 3], _forward: [f32; 3]) {}
    /// Short status for the window title (e.g. "streaming 40%").
    fn status(&self) -> Option<String> {
        None
    }
    /// Show style `i` (0-based) of a multi-style asset; its name when there is such a style
    /// and it was not already shown (keys 1..9).
    fn select_style(&mut self, _i: usize) -> Option<String> {
        None
    }
}

/// A whole asset, yielded once; of a multi-style file, its first style, and another whole
/// asset (same geometry, so the view stays where it is) each time a style is selected.
pub struct FileSource {
    asset: Option<Asset>,
    /// A multi-style file's styles (name, single-style asset); empty for other files.
    styles: Vec<(String, Asset)>,
    shown: usize,
}

impl FileSource {
    pub fn new(asset: Asset) -> FileSource {
        FileSource { asset: Some(asset), styles: Vec::new(), shown: 0 }
    }
    /// Read and validate an asset file (errors name the file).
    pub fn open(path: impl AsRef<Path>) -> Result<FileSource> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
        if !snerf_asset::layers::is_layered(&bytes) {
            return Ok(FileSource::new(Asset::read(path)?));
        }
        let l = snerf_asset::LayeredAsset::read(path)?;
        let styles: Vec<(String, Asset)> = l.names().into_iter().zip(l.layers).collect();
        let names: Vec<&str> = styles.iter().map(|(n, _)| n.as_str()).collect();
        eprintln!("snerf view: {}: styles {} (keys 1..{} switch)", path.display(), names.join(", "), names.len().min(9));
        Ok(FileSource { asset: Some(styles[0].1.clone()), styles, shown: 0 })
    }
    /// The styles of a multi-style file, in its order (empty for other files).
    pub fn style_names(&self) -> Vec<&str> {
        self.styles.iter().map(|(n, _)| n.as_str()).collect()
    }
}

impl AssetSource for FileSource {
    fn poll(&mut self) -> Option<AssetUpdate> {
        self.asset.take().map(|a| AssetUpdate::Whole(Box::new(a)))
    }
    fn select_style(&mut self, i: usize) -> Option<String> {
        if i == self.shown || i >= self.styles.len() {
            return None;
        }
        self.shown = i;
        self.asset = Some(self.styles[i].1.clone());
        Some(self.styles[i].0.clone())
    }
}

#[derive(Clone, Debug)]
pub struct ViewOptions {
    /// Window size in physical pixels (the image is rendered at the window's size).
    pub width: u32,
    pub height: u32,
    /// Vertical field of view, degrees.
    pub fov_y: f32,
    pub vsync: bool,
    /// Side-by-side left/right eyes.
    pub stereo: bool,
    /// Eye separation in world units (eyes at ∓ipd/2 along the camera's right axis).
    pub ipd: f32,
    /// Head poses (JSON list of {c2w, time}) played one per frame instead of the controls.
    pub pose_file: Option<PathBuf>,
    /// Present this many frames, then (after `screenshot`, if set) exit.
    pub frames: Option<u64>,
    /// Screenshot of the last of `frames` frames (PNG, written atomically).
    pub screenshot: Option<PathBuf>,
    /// Where F12 / Ctrl+S screenshots go.
    pub screenshot_dir: PathBuf,
    /// Seconds for one pass through a dynamic asset's time range.
    pub loop_seconds: f32,
    /// Give up (return an error) when the window is still open after this long.
    pub timeout: Option<Duration>,
    /// Print the frame time to stderr every second.
    pub print_stats: bool,
    pub title: String,
    pub gpu: GpuOptions,
}

impl Default for ViewOptions {
    fn default() -> Self {
        ViewOptions {
            width: 1280,
            height: 720,
            fov_y: 50.0,
            vsync: true,
            stereo: false,
            ipd: 0.064,
            pose_file: None,
            frames: None,
            screenshot: None,
            screenshot_dir: PathBuf::from("."),
            loop_seconds: 4.0,
            timeout: None,
            print_stats: true,
            title: "snerf view".to_string(),
            gpu: GpuOptions::default(),
        }
    }
}

/// The window's controls, for `--help` and the `H` key.
pub fn keys_help() -> &'static str {
    "mouse: left drag orbit | right drag look around (fly) | shift+left or middle drag pan | wheel zoom\n\
     keys:  W/A/S/D fly forward/left/back/right | Q/E down/up | shift: 4x faster | R reset view\n\
     \x20      P or space play/pause | [ and ] scrub time | F12 or Ctrl+S screenshot | V vsync on/off\n\
     \x20      1..9 style of a multi-style asset | H print these keys | Esc quit"
}

/// The style a key selects (Digit1..Digit9: 0..8).
fn style_key(code: KeyCode) -> Option<usize> {
    const KEYS: [KeyCode; 9] = [
        KeyCode::Digit1,
        KeyCode::Digit2,
        KeyCode::Digit3,
        KeyCode::Digit4,
        KeyCode::Digit5,
        KeyCode::Digit6,
        KeyCode::Digit7,
        KeyCode::Digit8,
        KeyCode::Digit9,
    ];
    KEYS.iter().position(|&k| k == code)
}

const SHORT_KEYS: &str =
    "drag orbit, WASD fly, wheel zoom, P play, [ ] scrub, F12 shot, V vsync, H keys, Esc quit";

/// Open a window and render `source`'s asset until closed (or `opts.frames` presented).
/// Errors (no display, no adapter, a lost device that cannot be recreated, a failed
/// screenshot) are returned, never panicked.
pub fn run_window(source: Box<dyn AssetSource>, opts: ViewOptions) -> Result<()> {
    let poses = match &opts.pose_file {
        Some(p) => load_poses(p)?,
        None => Vec::new(),
    };
    if opts.width == 0 || opts.height == 0 {
        bail!("window size {}x{} is empty", opts.width, opts.height);
    }
    let mut builder = EventLoop::builder();
    #[cfg(all(
        unix,
        not(target_os = "macos"),
        not(target_os = "android"),
        not(target_os = "ios")
    ))]
    {
        use winit::platform::x11::EventLoopBuilderExtX11;
        // Tests and embedding callers run us off the main thread.
        builder.with_any_thread(true);
    }
    let event_loop = builder.build().map_err(|e| {
        anyhow!(
            "cannot open a window: {} (is DISPLAY set? run under Xvfb for a virtual display)",
            e
        )
    })?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App::new(source, opts, poses);
    // Last line of defence: a panic inside the windowing stack (e.g. the X server going
    // away) becomes an error instead of taking the caller down.
    let run = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        event_loop.run_app(&mut app)
    }));
    // Drop GPU objects before the window.
    app.scene = None;
    app.gfx = None;
    match run {
        Ok(Ok(())) => app.result,
        Ok(Err(e)) => app
            .result
            .and(Err(anyhow!("window event loop failed: {}", e))),
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown panic".into());
            app.result
                .and(Err(anyhow!("the window system failed: {}", msg)))
        }
    }
}

struct Gfx {
    surface: wgpu::Surface<'static>,
    ctx: GpuContext,
    config: wgpu::SurfaceConfiguration,
    view_format: wgpu::TextureFormat,
    can_copy: bool,
    present: wgpu::RenderPipeline,
    screen: wgpu::Buffer,
    window: Arc<Window>,
}

struct Scene {
    asset: Asset,
    renderer: GpuRenderer,
    controller: Controller,
}

#[derive(Default)]
struct Input {
    buttons: HashSet<MouseButton>,
    keys: HashSet<KeyCode>,
    mods: ModifiersState,
    cursor: Option<(f64, f64)>,
}

struct Playback {
    t: f32,
    playing: bool,
}

struct Stats {
    frame_ms: Vec<f64>,
    last_print: Instant,
    last_frame: Option<Instant>,
    summary: String,
}

struct App {
    opts: ViewOptions,
    source: Box<dyn AssetSource>,
    poses: Vec<PoseSample>,
    gfx: Option<Gfx>,
    scene: Option<Scene>,
    result: Result<()>,
    input: Input,
    play: Playback,
    stats: Stats,
    presented: u64,
    marched_frames: u64,
    /// Asset time of the last frame drawn (playback, or the pose file's).
    shown_time: f32,
    shot_request: Option<PathBuf>,
    started: Instant,
    last_tick: Instant,
    device_recreations: u32,
    vsync: bool,
    /// A style key pressed (when, the style, whether its asset has arrived): the first frame
    /// drawn with it is reported with the time since the key (the switch's latency).
    style_key: Option<(Instant, String, bool)>,
}

impl App {
    fn new(source: Box<dyn AssetSource>, opts: ViewOptions, poses: Vec<PoseSample>) -> App {
        let now = Instant::now();
        App {
            style_key: None,
            vsync: opts.vsync,
            opts,
            source,
            poses,
            gfx: None,
            scene: None,
            result: Ok(()),
            input: Input::default(),
            play: Playback {
                t: 0.0,
                playing: true,
            },
            stats: Stats {
                frame_ms: Vec::new(),
                last_print: now,
                last_frame: None,
                summary: String::new(),
            },
            presented: 0,
            marched_frames: 0,
            shown_time: 0.0,
            shot_request: None,
            started: now,
            last_tick: now,
            device_recreations: 0,
        }
    }

    fn fail(&mut self, el: &ActiveEventLoop, e: anyhow::Error) {
        if self.result.is_ok() {
            self.result = Err(e);
        }
        el.exit();
    }

    fn init_gfx(&mut self, el: &ActiveEventLoop) -> Result<()> {
        let attrs = Window::default_attributes()
            .with_title(format!("{} — {}", self.opts.title, SHORT_KEYS))
            .with_inner_size(PhysicalSize::new(self.opts.width, self.opts.height));
        let window = Arc::new(
            el.create_window(attrs)
                .context("cannot create the window")?,
        );
        let instance = new_instance(&self.opts.gpu, Some(Box::new(el.owned_display_handle())));
        let gfx = Self::gfx_for_window(&self.opts, self.vsync, window, instance)?;
        eprintln!(
            "snerf view: {} ({}x{}, {:?})",
            gfx.ctx.adapter_info(),
            gfx.config.width,
            gfx.config.height,
            gfx.config.format
        );
        eprintln!("{}", keys_help());
        self.gfx = Some(gfx);
        Ok(())
    }

    fn reconfigure(&mut self) -> Result<()> {
        let Some(g) = self.gfx.as_mut() else {
            return Ok(());
        };
        let size = g.window.inner_size();
        if size.width == 0 || size.height == 0 {
            return Ok(()); // minimized: keep the old configuration, skip frames
        }
        g.config.width = size.width;
        g.config.height = size.height;
        g.config.present_mode = if self.vsync {
            wgpu::PresentMode::AutoVsync
        } else {
            wgpu::PresentMode::AutoNoVsync
        };
        g.ctx.scoped("configuring the window surface", || {
            g.surface.configure(&g.ctx.device, &g.config)
        })
    }

    /// Surface lost: make a new one for the same window.
    fn recreate_surface(&mut self) -> Result<()> {
        let Some(g) = self.gfx.as_mut() else {
            return Ok(());
        };
        g.surface = g
            .ctx
            .instance
            .create_surface(g.window.clone())
            .context("cannot recreate the window surface")?;
        self.reconfigure()
    }

    /// Device lost: new device on a fresh adapter request, re-upload the asset.
    fn recreate_device(&mut self, why: &str) -> Result<()> {
        self.device_recreations += 1;
        if self.device_recreations > 2 {
            bail!("GPU device lost again ({}); giving up", why);
        }
        eprintln!("snerf view: {}; recreating the GPU device", why);
        let Some(old) = self.gfx.take() else {
            return Ok(());
        };
        let (window, instance) = (old.window.clone(), old.ctx.instance.clone());
        // Keep the CPU-side asset and the view; drop everything on the old device.
        let kept = self.scene.take().map(|s| (s.asset, s.controller));
        drop(old);
        let g = Self::gfx_for_window(&self.opts, self.vsync, window, instance)?;
        let ctx = g.ctx.clone();
        self.gfx = Some(g);
        if let Some((asset, controller)) = kept {
            let renderer = GpuRenderer::with_context(ctx, &asset, self.opts.gpu.clone())?;
            self.scene = Some(Scene {
                asset,
                renderer,
                controller,
            });
        }
        Ok(())
    }

    fn gfx_for_window(
        opts: &ViewOptions,
        vsync: bool,
        window: Arc<Window>,
        instance: wgpu::Instance,
    ) -> Result<Gfx> {
        let surface = instance
            .create_surface(window.clone())
            .context("cannot create a drawing surface for the window")?;
        let ctx = GpuContext::from_instance(instance, Some(&surface), &opts.gpu)?;
        let caps = surface.get_capabilities(&ctx.adapter);
        if caps.formats.is_empty() {
            bail!(
                "the window surface is not supported by adapter {}",
                ctx.adapter_info()
            );
        }
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| !f.is_srgb())
            .unwrap_or(caps.formats[0]);
        let view_format = format.remove_srgb_suffix();
        let can_copy = caps.usages.contains(wgpu::TextureUsages::COPY_SRC);
        let size = window.inner_size();
        let config = wgpu::SurfaceConfiguration {
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | if can_copy {
                    wgpu::TextureUsages::COPY_SRC
                } else {
                    wgpu::TextureUsages::empty()
                },
            format,
            color_space: Default::default(),
            width: size.width.max(1),
            height: size.height.max(1),
            present_mode: if vsync {
                wgpu::PresentMode::AutoVsync
            } else {
                wgpu::PresentMode::AutoNoVsync
            },
            desired_maximum_frame_latency: 2,
            alpha_mode: caps
                .alpha_modes
                .first()
                .copied()
                .unwrap_or(wgpu::CompositeAlphaMode::Auto),
            view_formats: if view_format != format {
                vec![view_format]
            } else {
                vec![]
            },
        };
        let (present, screen) = present_pipeline(&ctx, view_format)?;
        let gfx = Gfx {
            surface,
            ctx,
            config,
            view_format,
            can_copy,
            present,
            screen,
            window,
        };
        gfx.ctx.scoped("configuring the window surface", || {
            gfx.surface.configure(&gfx.ctx.device, &gfx.config)
        })?;
        Ok(gfx)
    }

    fn apply_updates(&mut self) -> Result<()> {
        // Bounded per frame so a chatty stream cannot starve rendering.
        for _ in 0..256 {
            let Some(u) = self.source.poll() else { break };
            let Some(g) = self.gfx.as_ref() else { break };
            match u {
                AssetUpdate::Whole(asset) => {
                    if let Some(k) = &mut self.style_key {
                        k.2 = true;
                    }
                    // Another asset of the same header (another style of a multi-style file):
                    // the renderer stays (its pipeline and buffers fit); only the blocks, grids
                    // and view MLP are uploaded again.
                    if let Some(s) = self.scene.as_mut().filter(|s| s.asset.header == asset.header) {
                        let all: Vec<u32> = (0..asset.header.atlas_blocks).collect();
                        s.renderer.update_blocks(&asset, &all)?;
                        s.renderer.update_mlp(&asset.mlp)?;
                        s.asset = *asset;
                        continue;
                    }
                    let controller = match self.scene.take() {
                        Some(s)
                            if s.asset.header.kind == asset.header.kind
                                && s.asset.header.space == asset.header.space =>
                        {
                            s.controller
                        }
                        _ => Controller::new(&asset.header),
                    };
                    let renderer =
                        GpuRenderer::with_context(g.ctx.clone(), &asset, self.opts.gpu.clone())?;
                    if let Some(r) = asset.header.time_range {
                        self.play.t = self.play.t.clamp(r[0], r[1]);
                    }
                    self.scene = Some(Scene {
                        asset: *asset,
                        renderer,
                        controller,
                    });
                }
                part => {
                    let Some(s) = self.scene.as_mut() else {
                        continue;
                    };
                    match part.apply_part(&mut s.asset) {
                        Applied::Blocks(idx) => s.renderer.update_blocks(&s.asset, &idx)?,
                        Applied::Grid => s.renderer.update_grids(&s.asset)?,
                        Applied::Mlp => s.renderer.update_mlp(&s.asset.mlp)?,
                        Applied::Whole | Applied::Nothing => {}
                    }
                }
            }
        }
        Ok(())
    }

    fn tick(&mut self) {
        let now = Instant::now();
        let dt = (now - self.last_tick).as_secs_f32().min(0.25);
        self.last_tick = now;
        let Some(s) = self.scene.as_mut() else { return };
        if let Some(r) = s.asset.header.time_range {
            if self.play.playing && r[1] > r[0] {
                let span = r[1] - r[0];
                let mut t = self.play.t + dt * span / self.opts.loop_seconds.max(0.01);
                if t > r[1] {
                    t = r[0] + (t - r[1]) % span;
                }
                self.play.t = t;
            }
        }
        let k = &self.input.keys;
        let speed = 0.8
            * dt
            * if self.input.mods.shift_key() {
                4.0
            } else {
                1.0
            };
        let axis = |p: KeyCode, n: KeyCode| (k.contains(&p) as i32 - k.contains(&n) as i32) as f32;
        let (r, u, f) = (
            axis(KeyCode::KeyD, KeyCode::KeyA),
            axis(KeyCode::KeyE, KeyCode::KeyQ),
            axis(KeyCode::KeyW, KeyCode::KeyS),
        );
        if !self.input.mods.control_key() && (r != 0.0 || u != 0.0 || f != 0.0) {
            s.controller.fly(r * speed, u * speed, f * speed);
        }
    }

    fn scrub(&mut self, dir: f32) {
        let Some(r) = self.scene.as_ref().and_then(|s| s.asset.header.time_range) else {
            return;
        };
        self.play.t = (self.play.t + dir * (r[1] - r[0]) / 50.0).clamp(r[0], r[1]);
    }

    /// Views for this frame: mono or left/right halves; plus the (eye, forward) pose.
    fn views(&self, width: u32, height: u32) -> Option<(Vec<View>, [f32; 3], [f32; 3])> {
        let s = self.scene.as_ref()?;
        let (c2w, time) = if self.poses.is_empty() {
            (s.controller.c2w(), self.play.t)
        } else {
            let p = &self.poses[(self.presented as usize) % self.poses.len()];
            (p.c2w3(), p.time.unwrap_or(self.play.t))
        };
        let eye = [c2w[0][3], c2w[1][3], c2w[2][3]];
        let fwd = [-c2w[0][2], -c2w[1][2], -c2w[2][2]];
        let fov = self.opts.fov_y;
        let views = if self.opts.stereo && width >= 2 {
            let lw = width / 2;
            let (l, _) = stereo_pair(c2w, self.opts.ipd, lw, height, fov);
            let (_, r) = stereo_pair(c2w, self.opts.ipd, width - lw, height, fov);
            vec![
                View {
                    cam: l,
                    time,
                    x0: 0,
                },
                View {
                    cam: r,
                    time,
                    x0: lw,
                },
            ]
        } else {
            vec![View {
                cam: camera_from_c2w(c2w, width, height, fov),
                time,
                x0: 0,
            }]
        };
        Some((views, eye, fwd))
    }

    fn redraw(&mut self, el: &ActiveEventLoop) -> Result<()> {
        self.apply_updates()?;
        self.tick();
        let Some(g) = self.gfx.as_ref() else {
            return Ok(());
        };
        let (w, h) = (g.config.width, g.config.height);
        let views = self.views(w, h);
        if let Some((v, eye, fwd)) = &views {
            self.source.set_pose(*eye, *fwd);
            self.shown_time = v[0].time;
        }
        let (frame, suboptimal) = match g.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t) => (t, false),
            // Still presentable: draw it, then reconfigure for the next frame.
            wgpu::CurrentSurfaceTexture::Suboptimal(t) => (t, true),
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(())
            }
            wgpu::CurrentSurfaceTexture::Outdated => return self.reconfigure(),
            wgpu::CurrentSurfaceTexture::Lost => return self.recreate_surface(),
            wgpu::CurrentSurfaceTexture::Validation => {
                return g
                    .ctx
                    .check()
                    .and_then(|_| Err(anyhow!("the window surface reported a validation error")))
            }
        };
        let target = frame.texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(g.view_format),
            ..Default::default()
        });
        let mut enc = g
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("frame"),
            });
        let mut marched = false;
        if let (Some((views, _, _)), Some(s)) = (&views, self.scene.as_mut()) {
            match s.renderer.encode(&mut enc, w, h, views) {
                Ok(()) => marched = true,
                Err(e) if e.downcast_ref::<DeviceLostError>().is_some() => {
                    drop(enc);
                    drop(frame);
                    return self.recreate_device(&format!("{:#}", e));
                }
                Err(e) => return Err(e),
            }
        }
        let g = self.gfx.as_ref().expect("checked above");
        let bind = match (
            marched,
            self.scene.as_ref().and_then(|s| s.renderer.output_buffer()),
        ) {
            (true, Some(out)) => {
                g.ctx
                    .queue
                    .write_buffer(&g.screen, 0, bytemuck::cast_slice(&[w, h, 0u32, 0u32]));
                Some(g.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("present"),
                    layout: &g.present.get_bind_group_layout(0),
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: g.screen.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: out.as_entire_binding(),
                        },
                    ],
                }))
            }
            _ => None,
        };
        {
            let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("present"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: 0.12,
                            g: 0.12,
                            b: 0.12,
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                depth_stencil_attachment: None,
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if let Some(b) = &bind {
                pass.set_pipeline(&g.present);
                pass.set_bind_group(0, b, &[]);
                pass.draw(0..3, 0..1);
            }
        }
        // Screenshot of this frame: --frames N --screenshot FILE on the last frame, or a key.
        // --frames counts frames that showed the asset (a stream may take a while to start).
        let last = marched
            && self
                .opts
                .frames
                .is_some_and(|n| self.marched_frames + 1 >= n);
        let shot_path = if last && marched {
            self.opts.screenshot.clone()
        } else {
            None
        }
        .or_else(|| {
            if marched {
                self.shot_request.take()
            } else {
                None
            }
        });
        let shot = match &shot_path {
            Some(_) if g.can_copy => {
                let (buf, bpr) = surface_copy(g, &mut enc, &frame.texture)?;
                Some((buf, bpr))
            }
            _ => None,
        };
        g.ctx.queue.submit([enc.finish()]);
        if let Some(path) = &shot_path {
            match shot {
                Some((buf, bpr)) => {
                    let bytes: Vec<u8> = read_buffer(&g.ctx, &buf)?;
                    save_surface_png(&bytes, bpr, w, h, g.config.format, path)?;
                }
                None => {
                    // The swapchain cannot be copied on this platform: save the image we
                    // presented from (the march output) instead.
                    if let (Some((views, _, _)), Some(s)) = (views.as_ref(), self.scene.as_mut()) {
                        let f = s.renderer.render_views(w, h, views)?;
                        snerf_asset::write_png(&f, path)?;
                    }
                }
            }
            eprintln!("snerf view: screenshot {}", path.display());
        }
        g.ctx.queue.present(frame);
        self.presented += 1;
        if let (true, Some((at, name, true))) = (marched, &self.style_key) {
            // the frame's GPU work done, then the time since the key
            let _ = g.ctx.wait();
            eprintln!("snerf view: style {name} drawn {:.0} ms after its key", at.elapsed().as_secs_f64() * 1e3);
            self.style_key = None;
        }
        self.marched_frames += marched as u64;
        if suboptimal {
            self.reconfigure()?;
        }
        self.frame_stats();
        if last {
            el.exit();
        }
        self.check_timeout()
    }

    fn check_timeout(&self) -> Result<()> {
        match self.opts.timeout {
            Some(t) if self.started.elapsed() > t => match self.opts.frames {
                Some(n) => bail!(
                    "presented only {} of {} frames of the asset in {:?}",
                    self.marched_frames,
                    n,
                    t
                ),
                None => bail!(
                    "window still open after {:?} ({} frames presented)",
                    t,
                    self.presented
                ),
            },
            _ => Ok(()),
        }
    }

    fn frame_stats(&mut self) {
        let now = Instant::now();
        if let Some(prev) = self.stats.last_frame {
            self.stats.frame_ms.push((now - prev).as_secs_f64() * 1e3);
        }
        self.stats.last_frame = Some(now);
        if now - self.stats.last_print >= Duration::from_secs(1) && !self.stats.frame_ms.is_empty()
        {
            let n = self.stats.frame_ms.len();
            let m = median(&mut self.stats.frame_ms);
            self.stats.frame_ms.clear();
            self.stats.last_print = now;
            let (w, h) = self
                .gfx
                .as_ref()
                .map_or((0, 0), |g| (g.config.width, g.config.height));
            let time = match self.scene.as_ref().and_then(|s| s.asset.header.time_range) {
                Some(_) => format!(
                    ", t {:.3}{}",
                    self.shown_time,
                    if self.play.playing { "" } else { " (paused)" }
                ),
                None => String::new(),
            };
            let status = self
                .source
                .status()
                .map(|s| format!(", {}", s))
                .unwrap_or_default();
            self.stats.summary = format!(
                "{:.1} ms/frame ({:.1} fps), {}x{}{}{}{}",
                m,
                1e3 / m,
                w,
                h,
                if self.opts.stereo { " stereo" } else { "" },
                time,
                status
            );
            if self.opts.print_stats {
                eprintln!("snerf view: {} over {} frames", self.stats.summary, n);
            }
            if let Some(g) = &self.gfx {
                g.window.set_title(&format!(
                    "{} — {} — {}",
                    self.opts.title, self.stats.summary, SHORT_KEYS
                ));
            }
        }
    }

    fn key(&mut self, el: &ActiveEventLoop, code: KeyCode) {
        let ctrl = self.input.mods.control_key();
        match code {
            KeyCode::Escape => el.exit(),
            KeyCode::KeyR => {
                if let Some(s) = self.scene.as_mut() {
                    s.controller.reset();
                }
            }
            KeyCode::KeyP | KeyCode::Space => self.play.playing = !self.play.playing,
            KeyCode::BracketLeft => self.scrub(-1.0),
            KeyCode::BracketRight => self.scrub(1.0),
            KeyCode::KeyH | KeyCode::F1 => eprintln!("{}", keys_help()),
            KeyCode::KeyV => {
                self.vsync = !self.vsync;
                eprintln!(
                    "snerf view: vsync {}",
                    if self.vsync { "on" } else { "off" }
                );
                if let Err(e) = self.reconfigure() {
                    self.fail(el, e);
                }
            }
            KeyCode::F12 => self.request_shot(),
            KeyCode::KeyS if ctrl => self.request_shot(),
            _ => {
                if let Some(i) = style_key(code) {
                    if let Some(name) = self.source.select_style(i) {
                        eprintln!("snerf view: style {} ({name})", i + 1);
                        self.style_key = Some((Instant::now(), name, false));
                    }
                }
            }
        }
    }

    fn request_shot(&mut self) {
        let secs = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let name = format!("snerf-{}-{:05}.png", secs, self.presented);
        self.shot_request = Some(self.opts.screenshot_dir.join(name));
    }
}

fn present_pipeline(
    ctx: &GpuContext,
    view_format: wgpu::TextureFormat,
) -> Result<(wgpu::RenderPipeline, wgpu::Buffer)> {
    let device = ctx.device.clone();
    ctx.scoped("creating the present pipeline", || {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("present.wgsl"),
            source: wgpu::ShaderSource::Wgsl(PRESENT_WGSL.into()),
        });
        let present = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("present"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: view_format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let screen = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("present screen"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        (present, screen)
    })
}

/// Copy the swapchain image into a mappable buffer (rows padded to 256 bytes).
fn surface_copy(
    g: &Gfx,
    enc: &mut wgpu::CommandEncoder,
    tex: &wgpu::Texture,
) -> Result<(wgpu::Buffer, u32)> {
    let (w, h) = (g.config.width, g.config.height);
    let bpr =
        (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buf = g.ctx.scoped("allocating the screenshot buffer", || {
        g.ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("screenshot"),
            size: bpr as u64 * h as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    })?;
    enc.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: tex,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buf,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(bpr),
                rows_per_image: Some(h),
            },
        },
        wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
    );
    Ok((buf, bpr))
}

fn save_surface_png(
    bytes: &[u8],
    bpr: u32,
    w: u32,
    h: u32,
    format: wgpu::TextureFormat,
    path: &Path,
) -> Result<()> {
    let bgra = matches!(
        format,
        wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
    );
    let rgba = matches!(
        format,
        wgpu::TextureFormat::Rgba8Unorm | wgpu::TextureFormat::Rgba8UnormSrgb
    );
    if !bgra && !rgba {
        bail!(
            "{}: cannot save a screenshot of a {:?} swapchain",
            path.display(),
            format
        );
    }
    let mut rgb = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h as usize {
        let row = &bytes[y * bpr as usize..y * bpr as usize + w as usize * 4];
        for p in row.chunks_exact(4) {
            if bgra {
                rgb.extend_from_slice(&[p[2], p[1], p[0]]);
            } else {
                rgb.extend_from_slice(&p[..3]);
            }
        }
    }
    let img = image::RgbImage::from_raw(w, h, rgb).ok_or_else(|| anyhow!("bad screenshot size"))?;
    let mut png = std::io::Cursor::new(Vec::new());
    img.write_to(&mut png, image::ImageFormat::Png)
        .map_err(|e| anyhow!("{}: PNG encoding failed: {}", path.display(), e))?;
    snerf_asset::atomic::write_atomic(path, &png.into_inner())
}

impl ApplicationHandler for App {
    fn resumed(&mut self, el: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        if let Err(e) = self.init_gfx(el) {
            self.fail(el, e);
        }
    }

    fn window_event(&mut self, el: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        if self.result.is_err() {
            return;
        }
        match event {
            WindowEvent::CloseRequested | WindowEvent::Destroyed => {
                // Closing mid-frame: stop; GPU objects are dropped after the loop returns.
                el.exit();
            }
            WindowEvent::Resized(_) => {
                if let Err(e) = self.reconfigure() {
                    self.fail(el, e);
                }
            }
            WindowEvent::ModifiersChanged(m) => self.input.mods = m.state(),
            WindowEvent::MouseInput { state, button, .. } => {
                if state == ElementState::Pressed {
                    self.input.buttons.insert(button);
                } else {
                    self.input.buttons.remove(&button);
                }
            }
            WindowEvent::CursorLeft { .. } => self.input.cursor = None,
            WindowEvent::CursorMoved { position, .. } => {
                let prev = self.input.cursor.replace((position.x, position.y));
                let (Some((px, py)), Some(s)) = (prev, self.scene.as_mut()) else {
                    return;
                };
                let (dx, dy) = ((position.x - px) as f32, (position.y - py) as f32);
                let b = &self.input.buttons;
                if b.contains(&MouseButton::Middle)
                    || (b.contains(&MouseButton::Left) && self.input.mods.shift_key())
                {
                    s.controller.pan(dx, dy);
                } else if b.contains(&MouseButton::Left) {
                    s.controller.orbit(dx, dy);
                } else if b.contains(&MouseButton::Right) {
                    s.controller.look(dx, dy);
                }
            }
            WindowEvent::MouseWheel { delta, .. } => {
                let steps = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => (p.y / 50.0) as f32,
                };
                if let Some(s) = self.scene.as_mut() {
                    s.controller.zoom(steps);
                }
            }
            WindowEvent::KeyboardInput { event, .. } => {
                if let PhysicalKey::Code(code) = event.physical_key {
                    if event.state == ElementState::Pressed {
                        self.input.keys.insert(code);
                        if !event.repeat {
                            self.key(el, code);
                        }
                    } else {
                        self.input.keys.remove(&code);
                    }
                }
            }
            WindowEvent::Focused(false) => {
                self.input.keys.clear();
                self.input.buttons.clear();
            }
            WindowEvent::RedrawRequested => {
                if el.exiting() {
                    return;
                }
                if let Err(e) = self.redraw(el) {
                    self.fail(el, e);
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, el: &ActiveEventLoop) {
        if el.exiting() {
            return;
        }
        if let Err(e) = self.check_timeout() {
            self.fail(el, e);
            return;
        }
        if let Some(g) = &self.gfx {
            g.window.request_redraw();
        }
    }

    fn exiting(&mut self, _el: &ActiveEventLoop) {
        // Release GPU objects while the window (and its display connection) still exists.
        self.scene = None;
        self.gfx = None;
    }
}
