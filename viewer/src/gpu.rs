//! The wgpu renderer: uploads an asset (atlas -> one 3D texture of blocks, or two with
//! hardware filtering; indirection grids -> a storage buffer, view MLP -> a uniform buffer),
//! builds the one shader variant the scene needs (`shader_variant`), and ray-marches one or
//! more views into a float output buffer that is either read back (headless, tests) or
//! presented (window).

use anyhow::{anyhow, bail, Context, Result};
use std::fmt;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use snerf_asset::{Asset, Camera, Frame, Header, ViewMlp, EMPTY};

pub use snerf_geometry::march::{ATLAS_FILTER_WGSL, ATLAS_LOAD_WGSL, MARCH_WGSL};
pub use snerf_geometry::march::PRESENT_WGSL;

/// Workgroup edge of the march shader (WG x WG pixels per workgroup).
const WG: u32 = snerf_geometry::march::WORKGROUP;
const CHANNELS: usize = 8;

/// Renderer settings. The defaults are what the viewer uses.
#[derive(Clone, Debug, Default)]
pub struct GpuOptions {
    /// Sample the atlas with hardware trilinear filtering (rgba8unorm + sampler) instead of
    /// 8 texel loads and a manual trilinear (the default, which matches the CPU reference).
    pub hardware_filter: bool,
    /// Ask the device for at most this max 3D texture edge (emulates a smaller GPU).
    pub max_texture_dimension_3d: Option<u32>,
    /// Backends to try; default: `WGPU_BACKEND` from the environment, else Vulkan + GL.
    pub backends: Option<wgpu::Backends>,
}

/// No usable GPU adapter: callers fall back to the CPU reference renderer on this error
/// (`err.downcast_ref::<NoAdapterError>()`).
#[derive(Debug, Clone)]
pub struct NoAdapterError(pub String);

impl fmt::Display for NoAdapterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "no GPU adapter found ({}); on Debian install mesa-vulkan-drivers and libvulkan1 for \
             lavapipe, or use the CPU reference renderer",
            self.0
        )
    }
}
impl std::error::Error for NoAdapterError {}

/// The device was lost (driver reset, GPU removed); recreate the renderer or give up.
#[derive(Debug, Clone)]
pub struct DeviceLostError(pub String);

impl fmt::Display for DeviceLostError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "GPU device lost: {}", self.0)
    }
}
impl std::error::Error for DeviceLostError {}

/// The asset (or the requested image) does not fit one of the device's limits.
#[derive(Debug, Clone)]
pub struct LimitError {
    /// wgpu limit name, e.g. `max_texture_dimension_3d`.
    pub limit: &'static str,
    pub needed: u64,
    pub max: u64,
    pub what: String,
}

impl fmt::Display for LimitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} exceeds the GPU limit {} = {} (needs {})",
            self.what, self.limit, self.max, self.needed
        )
    }
}
impl std::error::Error for LimitError {}

fn backends(opts: &GpuOptions) -> wgpu::Backends {
    opts.backends
        .or_else(wgpu::Backends::from_env)
        .unwrap_or(wgpu::Backends::VULKAN | wgpu::Backends::GL)
}

pub(crate) fn new_instance(
    opts: &GpuOptions,
    display: Option<Box<dyn wgpu::wgt::WgpuHasDisplayHandle>>,
) -> wgpu::Instance {
    let mut desc = match display {
        Some(d) => wgpu::InstanceDescriptor::new_with_display_handle(d),
        None => wgpu::InstanceDescriptor::new_without_display_handle(),
    };
    desc.backends = backends(opts);
    desc.flags = wgpu::InstanceFlags::from_env_or_default();
    wgpu::Instance::new(desc)
}

/// Device + queue on one adapter, shared by renderers (and the window's surface).
#[derive(Clone)]
pub struct GpuContext {
    pub(crate) instance: wgpu::Instance,
    pub(crate) adapter: wgpu::Adapter,
    pub(crate) device: wgpu::Device,
    pub(crate) queue: wgpu::Queue,
    info: wgpu::AdapterInfo,
    lost: Arc<Mutex<Option<String>>>,
    errors: Arc<Mutex<Vec<String>>>,
}

impl GpuContext {
    /// Headless context on the best adapter (Vulkan first; lavapipe counts).
    pub fn new(opts: &GpuOptions) -> Result<GpuContext> {
        let instance = new_instance(opts, None);
        GpuContext::from_instance(instance, None, opts)
    }

    pub(crate) fn from_instance(
        instance: wgpu::Instance,
        surface: Option<&wgpu::Surface<'_>>,
        opts: &GpuOptions,
    ) -> Result<GpuContext> {
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: surface,
            apply_limit_buckets: false,
        }));
        let adapter = match adapter {
            Ok(a) => a,
            Err(e) => {
                let seen = pollster::block_on(instance.enumerate_adapters(backends(opts)));
                let names: Vec<String> = seen
                    .iter()
                    .map(|a| format!("{} ({:?})", a.get_info().name, a.get_info().backend))
                    .collect();
                let detail = if names.is_empty() {
                    format!("backends {:?}: none present; {}", backends(opts), e)
                } else {
                    format!("adapters {} cannot be used: {}", names.join(", "), e)
                };
                return Err(NoAdapterError(detail).into());
            }
        };
        let info = adapter.get_info();
        let down = adapter.get_downlevel_capabilities();
        if !down.flags.contains(wgpu::DownlevelFlags::COMPUTE_SHADERS) {
            return Err(NoAdapterError(format!(
                "adapter {} ({:?}) has no compute shaders",
                info.name, info.backend
            ))
            .into());
        }
        let mut limits = adapter.limits();
        if let Some(m) = opts.max_texture_dimension_3d {
            limits.max_texture_dimension_3d = limits.max_texture_dimension_3d.min(m.max(1));
        }
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("snerf-viewer"),
            required_features: wgpu::Features::empty(),
            required_limits: limits,
            experimental_features: wgpu::ExperimentalFeatures::disabled(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::Off,
        }))
        .map_err(|e| {
            anyhow!(
                "{} ({:?}): cannot open the device: {}",
                info.name,
                info.backend,
                e
            )
        })?;
        let lost = Arc::new(Mutex::new(None));
        let errors = Arc::new(Mutex::new(Vec::new()));
        {
            let lost = lost.clone();
            device.set_device_lost_callback(move |reason, msg| {
                if let Ok(mut l) = lost.lock() {
                    *l = Some(if msg.is_empty() {
                        format!("{:?}", reason)
                    } else {
                        format!("{:?}: {}", reason, msg)
                    });
                }
            });
            // wgpu's default handler panics; record instead and turn into errors.
            let errors = errors.clone();
            device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
                if let Ok(mut v) = errors.lock() {
                    if v.len() < 16 {
                        v.push(e.to_string());
                    }
                }
            }));
        }
        Ok(GpuContext {
            instance,
            adapter,
            device,
            queue,
            info,
            lost,
            errors,
        })
    }

    /// "name (backend, driver driver_info)".
    pub fn adapter_info(&self) -> String {
        let i = &self.info;
        format!(
            "{} ({:?}, {:?}, {} {})",
            i.name, i.backend, i.device_type, i.driver, i.driver_info
        )
    }

    /// Destroy the device as a driver reset would (tests of the lost-device paths).
    #[doc(hidden)]
    pub fn destroy_device_for_test(&self) {
        self.device.destroy();
    }

    pub fn limits(&self) -> wgpu::Limits {
        self.device.limits()
    }

    /// Lost device or any error wgpu reported outside an error scope since the last check.
    pub(crate) fn check(&self) -> Result<()> {
        if let Some(l) = self.lost.lock().ok().and_then(|l| l.clone()) {
            return Err(DeviceLostError(l).into());
        }
        let errs: Vec<String> = self
            .errors
            .lock()
            .map(|mut v| std::mem::take(&mut *v))
            .unwrap_or_default();
        if !errs.is_empty() {
            bail!("GPU error: {}", errs.join("; "));
        }
        Ok(())
    }

    pub(crate) fn wait(&self) -> Result<()> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| anyhow!("waiting for the GPU failed: {}", e))?;
        self.check()
    }

    /// Run `f` inside validation + out-of-memory error scopes.
    pub(crate) fn scoped<T>(&self, what: &str, f: impl FnOnce() -> T) -> Result<T> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let val = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = f();
        let v = pollster::block_on(val.pop());
        let o = pollster::block_on(oom.pop());
        if let Some(e) = o {
            bail!("{}: GPU out of memory: {}", what, e);
        }
        if let Some(e) = v {
            bail!("{}: {}", what, e);
        }
        Ok(out)
    }
}

/// Is there a usable adapter? Its description, or None.
pub fn gpu_available() -> Option<String> {
    GpuContext::new(&GpuOptions::default())
        .ok()
        .map(|c| c.adapter_info())
}

/// How atlas blocks are laid out in the 3D textures: block i sits at
/// (i % nx, (i / nx) % ny, i / (nx ny)) * (block + 2).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AtlasLayout {
    pub edge: u32,
    pub nx: u32,
    pub ny: u32,
    pub nz: u32,
}

impl AtlasLayout {
    /// Fit `blocks` blocks of edge `edge` into a 3D texture no larger than `max_dim` per axis.
    pub fn plan(
        blocks: u32,
        edge: u32,
        max_dim: u32,
    ) -> std::result::Result<AtlasLayout, LimitError> {
        let n = blocks.max(1) as u64;
        let cap = (max_dim / edge) as u64;
        let fail = || LimitError {
            limit: "max_texture_dimension_3d",
            needed: edge as u64 * (n as f64).cbrt().ceil() as u64,
            max: max_dim as u64,
            what: format!(
                "the atlas ({} blocks of {}^3 voxels; at most {} fit)",
                blocks,
                edge,
                cap * cap * cap
            ),
        };
        if cap == 0 || cap * cap * cap < n {
            return Err(fail());
        }
        // Grid entries pack the block position 10 bits per axis (see march.wgsl).
        let cap = cap.min(1024);
        let mut nx = ((n as f64).cbrt().ceil() as u64).clamp(1, cap);
        let mut ny = (n.div_ceil(nx) as f64).sqrt().ceil() as u64;
        ny = ny.clamp(1, cap);
        let mut nz = n.div_ceil(nx * ny);
        if nz > cap {
            nx = cap;
            ny = cap;
            nz = n.div_ceil(cap * cap);
        }
        if nz > cap {
            return Err(fail());
        }
        Ok(AtlasLayout {
            edge,
            nx: nx as u32,
            ny: ny as u32,
            nz: nz as u32,
        })
    }

    pub fn texels(&self) -> [u32; 3] {
        [
            self.nx * self.edge,
            self.ny * self.edge,
            self.nz * self.edge,
        ]
    }

    /// Position of `block` in blocks, packed for the shader: x | y << 10 | z << 20.
    pub fn packed(&self, block: u32) -> u32 {
        let (x, y, z) = (
            block % self.nx,
            block / self.nx % self.ny,
            block / (self.nx * self.ny),
        );
        x | y << 10 | z << 20
    }

    pub fn origin(&self, block: u32) -> [u32; 3] {
        [
            block % self.nx * self.edge,
            block / self.nx % self.ny * self.edge,
            block / (self.nx * self.ny) * self.edge,
        ]
    }
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    c2w: [[f32; 4]; 3],
    intr: [f32; 4],
    view: [u32; 4],
    rot: [[f32; 4]; 3],
    center_scale: [f32; 4],
    ndc0: [f32; 4],
    march: [f32; 4],
    dens: [f32; 4],
    background: [f32; 4],
    grid: [u32; 4],
    frames: [u32; 4],
    inv_tex: [f32; 4],
}

/// Keyframes around `t` and the blend weight (`snerf_geometry::time_slot`, as the CPU
/// reference uses).
pub fn time_slot(h: &Header, t: f32) -> (usize, usize, f32) {
    let s = snerf_geometry::time_slot(h.frames.as_deref().unwrap_or(&[]), |k| k.time, t);
    (s.k0, s.k1, s.w)
}

/// Output buffers for one image (all views side by side).
struct Target {
    width: u32,
    height: u32,
    rgba: wgpu::Buffer,
    depth: wgpu::Buffer,
    /// The first pass's opacity (march_compute.wgsl `cover`), read by the silhouette pass.
    _cover: wgpu::Buffer,
    /// Per view: the centre pass's bind group, then the silhouette pass's (its own params).
    bind_groups: Vec<wgpu::BindGroup>,
}

/// A view to render into the shared output: camera, time, x offset in the output.
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub cam: Camera,
    pub time: f32,
    pub x0: u32,
}

/// The GPU renderer of one asset.
pub struct GpuRenderer {
    ctx: GpuContext,
    opts: GpuOptions,
    header: Header,
    layout: AtlasLayout,
    /// Default: one rg32uint texture (8 bytes per voxel; r32uint, 4 bytes, for a diffuse
    /// asset); hardware filter: two rgba8unorm (the second a 1-texel stand-in for a diffuse
    /// asset).
    tex: Vec<wgpu::Texture>,
    sampler: Option<wgpu::Sampler>,
    grid_buf: wgpu::Buffer,
    mlp_buf: wgpu::Buffer,
    pipeline: wgpu::ComputePipeline,
    params: Vec<wgpu::Buffer>,
    target: Option<Target>,
    /// Grid entries (all frames) as uploaded: non-present blocks replaced by EMPTY.
    grid_host: Vec<u32>,
}

impl GpuRenderer {
    /// Open the best adapter and upload `asset`. Errors (never panics) when there is no
    /// adapter (`NoAdapterError`), or the asset exceeds a device limit (`LimitError`).
    pub fn new(asset: &Asset) -> Result<GpuRenderer> {
        GpuRenderer::with_options(asset, GpuOptions::default())
    }

    pub fn with_options(asset: &Asset, opts: GpuOptions) -> Result<GpuRenderer> {
        // Cheap header checks first, before opening a device and before any allocation.
        asset.header.validate().context("asset header")?;
        let ctx = GpuContext::new(&opts)?;
        GpuRenderer::with_context(ctx, asset, opts)
    }

    /// Upload `asset` on an existing device (the window shares the device with its surface).
    pub fn with_context(ctx: GpuContext, asset: &Asset, opts: GpuOptions) -> Result<GpuRenderer> {
        let h = asset.header.clone();
        h.validate().context("asset header")?;
        check_consistent(asset)?;
        let limits = ctx.device.limits();
        let layout =
            AtlasLayout::plan(h.atlas_blocks, h.block + 2, limits.max_texture_dimension_3d)
                .map_err(anyhow::Error::new)?;
        let g3 = h.grid_dim().pow(3) as u64;
        let grid_bytes = g3 * h.num_frames() as u64 * 4;
        for (limit, max) in [
            (
                "max_storage_buffer_binding_size",
                limits.max_storage_buffer_binding_size,
            ),
            ("max_buffer_size", limits.max_buffer_size),
        ] {
            if grid_bytes > max {
                return Err(LimitError {
                    limit,
                    needed: grid_bytes,
                    max,
                    what: format!(
                        "the indirection grids ({} frames of {}^3 cells)",
                        h.num_frames(),
                        h.grid_dim()
                    ),
                }
                .into());
            }
        }
        let device = &ctx.device;
        let texels = layout.texels();
        let split = texel_split(opts.hardware_filter, h.diffuse);
        let fmt = match (opts.hardware_filter, split[0].len()) {
            (true, _) => wgpu::TextureFormat::Rgba8Unorm,
            // density and RGB only: the features of a diffuse asset are zero and never read
            (false, 4) => wgpu::TextureFormat::R32Uint,
            (false, _) => wgpu::TextureFormat::Rg32Uint,
        };
        let (tex, sampler, grid_buf, mlp_buf, pipeline) =
            ctx.scoped("uploading the asset", || {
                let mk_sized = |label, size: [u32; 3]| {
                    device.create_texture(&wgpu::TextureDescriptor {
                        label: Some(label),
                        size: wgpu::Extent3d {
                            width: size[0],
                            height: size[1],
                            depth_or_array_layers: size[2],
                        },
                        mip_level_count: 1,
                        sample_count: 1,
                        dimension: wgpu::TextureDimension::D3,
                        format: fmt,
                        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                        view_formats: &[],
                    })
                };
                let mut tex: Vec<wgpu::Texture> = split.iter().map(|_| mk_sized("atlas", texels)).collect();
                if opts.hardware_filter && tex.len() == 1 {
                    // the filter shader binds a features texture; a diffuse one never reads it
                    tex.push(mk_sized("no features (diffuse)", [1, 1, 1]));
                }
                let sampler = opts.hardware_filter.then(|| {
                    device.create_sampler(&wgpu::SamplerDescriptor {
                        label: Some("atlas trilinear"),
                        mag_filter: wgpu::FilterMode::Linear,
                        min_filter: wgpu::FilterMode::Linear,
                        ..Default::default()
                    })
                });
                let grid_buf = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("indirection grids"),
                    size: grid_bytes.max(4),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                let mlp_buf = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("view mlp"),
                    size: (MLP_GPU_FLOATS * 4) as u64,
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                let pipeline = build_pipeline(device, &h, opts.hardware_filter);
                (tex, sampler, grid_buf, mlp_buf, pipeline)
            })?;
        let mut r = GpuRenderer {
            ctx,
            opts,
            header: h,
            layout,
            tex,
            sampler,
            grid_buf,
            mlp_buf,
            pipeline,
            params: Vec::new(),
            target: None,
            grid_host: Vec::new(),
        };
        r.upload_all_blocks(asset)?;
        r.update_grids(asset)?;
        r.update_mlp(&asset.mlp)?;
        r.ctx.check()?;
        Ok(r)
    }

    pub fn adapter_info(&self) -> String {
        self.ctx.adapter_info()
    }

    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    pub fn header(&self) -> &Header {
        &self.header
    }

    pub fn atlas_layout(&self) -> AtlasLayout {
        self.layout
    }

    /// Replace the asset on the same device (a new scene, or a stream restarting).
    pub fn set_asset(&mut self, asset: &Asset) -> Result<()> {
        let r = GpuRenderer::with_context(self.ctx.clone(), asset, self.opts.clone())?;
        *self = r;
        Ok(())
    }

    /// Bytes of GPU texture memory the atlas takes.
    pub fn atlas_texture_bytes(&self) -> u64 {
        let t = self.layout.texels();
        let voxel: usize = self.texel_split().iter().map(|r| r.len()).sum();
        t.iter().map(|&n| n as u64).product::<u64>() * voxel as u64
    }

    fn texel_split(&self) -> Vec<std::ops::Range<usize>> {
        texel_split(self.opts.hardware_filter, self.header.diffuse)
    }

    /// Copy block `src` (apron-inclusive, 8 bytes per voxel) into per-texture staging
    /// images of `w` x `h` texels per slice at texel (ox, oy, 0).
    fn scatter_block(
        &self,
        src: &[u8],
        dst: &mut [Vec<u8>],
        w: usize,
        h: usize,
        ox: usize,
        oy: usize,
    ) {
        let e = self.layout.edge as usize;
        for (range, out) in self.texel_split().into_iter().zip(dst.iter_mut()) {
            let n = range.len();
            for z in 0..e {
                for y in 0..e {
                    let row = ((z * h + oy + y) * w + ox) * n;
                    let s = (z * e + y) * e * CHANNELS;
                    for x in 0..e {
                        let v = s + x * CHANNELS;
                        out[row + x * n..row + (x + 1) * n]
                            .copy_from_slice(&src[v + range.start..v + range.end]);
                    }
                }
            }
        }
    }

    fn write_region(&self, data: &[Vec<u8>], origin: [u32; 3], size: [u32; 3]) {
        for ((t, d), range) in self.tex.iter().zip(data).zip(self.texel_split()) {
            let n = range.len() as u32;
            self.ctx.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: t,
                    mip_level: 0,
                    origin: wgpu::Origin3d {
                        x: origin[0],
                        y: origin[1],
                        z: origin[2],
                    },
                    aspect: wgpu::TextureAspect::All,
                },
                d,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(size[0] * n),
                    rows_per_image: Some(size[1]),
                },
                wgpu::Extent3d {
                    width: size[0],
                    height: size[1],
                    depth_or_array_layers: size[2],
                },
            );
        }
    }

    fn write_blocks(&self, asset: &Asset, blocks: impl Iterator<Item = u32>) {
        let e = self.layout.edge as usize;
        let bb = asset.block_bytes();
        let mut data: Vec<Vec<u8>> = self
            .texel_split()
            .iter()
            .map(|r| vec![0u8; e * e * e * r.len()])
            .collect();
        for i in blocks {
            let Some(src) = asset.atlas.get(i as usize * bb..(i as usize + 1) * bb) else {
                continue;
            };
            self.scatter_block(src, &mut data, e, e, 0, 0);
            self.write_region(&data, self.layout.origin(i), [e as u32; 3]);
        }
    }

    /// Whole atlas, one layer of blocks (nx x ny blocks, `edge` slices) per upload.
    fn upload_all_blocks(&mut self, asset: &Asset) -> Result<()> {
        let l = self.layout;
        let e = l.edge as usize;
        let bb = asset.block_bytes();
        let (w, hgt) = (l.nx as usize * e, l.ny as usize * e);
        let per_layer = (l.nx * l.ny) as usize;
        let n = asset.header.atlas_blocks as usize;
        for bz in 0..l.nz as usize {
            let first = bz * per_layer;
            if first >= n {
                break;
            }
            let mut data: Vec<Vec<u8>> = self
                .texel_split()
                .iter()
                .map(|r| vec![0u8; w * hgt * e * r.len()])
                .collect();
            for i in first..(first + per_layer).min(n) {
                if !asset.present.get(i).copied().unwrap_or(false) {
                    continue;
                }
                let Some(src) = asset.atlas.get(i * bb..(i + 1) * bb) else {
                    continue;
                };
                let k = i - first;
                self.scatter_block(
                    src,
                    &mut data,
                    w,
                    hgt,
                    (k % l.nx as usize) * e,
                    (k / l.nx as usize) * e,
                );
            }
            self.write_region(
                &data,
                [0, 0, (bz * e) as u32],
                [w as u32, hgt as u32, e as u32],
            );
            // Keep staging memory bounded on big atlases.
            self.ctx.queue.submit([]);
        }
        self.ctx.check()
    }

    /// Blocks `blocks` of `asset` arrived or changed (streaming): upload them and make the
    /// grid cells that point at them visible. Indices out of range are ignored.
    pub fn update_blocks(&mut self, asset: &Asset, blocks: &[u32]) -> Result<()> {
        if asset.header != self.header {
            return self.set_asset(asset);
        }
        let ok: Vec<u32> = blocks
            .iter()
            .copied()
            .filter(|&i| asset.present.get(i as usize).copied().unwrap_or(false))
            .collect();
        self.write_blocks(asset, ok.iter().copied());
        self.update_grids(asset)
    }

    /// (Re)upload every frame's indirection grid: cells whose block has not arrived, and
    /// frames whose grid has not arrived, are empty.
    pub fn update_grids(&mut self, asset: &Asset) -> Result<()> {
        let g3 = self.header.grid_dim().pow(3);
        let frames = self.header.num_frames();
        let mut host = vec![EMPTY; g3 * frames];
        for f in 0..frames {
            if let Some(grid) = asset.grids.get(f).filter(|g| g.len() == g3) {
                for (d, &e) in host[f * g3..(f + 1) * g3].iter_mut().zip(grid) {
                    if snerf_asset::motion::is_motion(e) {
                        *d = e;
                    } else if e != EMPTY && asset.present.get(e as usize).copied().unwrap_or(false) {
                        *d = self.layout.packed(e);
                    }
                }
            }
        }
        if host != self.grid_host {
            self.ctx
                .queue
                .write_buffer(&self.grid_buf, 0, bytemuck::cast_slice(&host));
            self.grid_host = host;
        }
        self.ctx.check()
    }

    pub fn update_mlp(&mut self, mlp: &ViewMlp) -> Result<()> {
        mlp.validate()?;
        self.ctx
            .queue
            .write_buffer(&self.mlp_buf, 0, bytemuck::cast_slice(&mlp_gpu_layout(mlp)));
        self.ctx.check()
    }

    fn params_for(&self, v: &View, stride: u32) -> Params {
        let h = &self.header;
        let s = &h.space;
        let c = &v.cam;
        let (k0, k1, w) = time_slot(h, v.time);
        let g3 = h.grid_dim().pow(3) as u32;
        let n = s.ndc.unwrap_or(snerf_asset::Ndc {
            fx: 1.0,
            fy: 1.0,
            width: 1.0,
            height: 1.0,
            near: 1.0,
            xy_extent: 1.0,
        });
        let t = self.layout.texels();
        let row = |r: [f32; 3]| [r[0], r[1], r[2], 0.0];
        Params {
            c2w: c.c2w,
            intr: [c.fx, c.fy, c.cx, c.cy],
            view: [c.width, c.height, v.x0, stride],
            rot: [row(s.rot[0]), row(s.rot[1]), row(s.rot[2])],
            center_scale: [s.center[0], s.center[1], s.center[2], s.scale],
            ndc0: [n.fx, n.fy, n.width, n.height],
            march: [n.near, n.xy_extent, h.march.step, h.march.t_terminate],
            dens: [h.density.logit_min, h.density.logit_max, w, f32::from_bits(h.motion_ref.unwrap_or(0) * g3)],
            background: [h.background[0], h.background[1], h.background[2], if h.colour_by_density { 1.0 } else { 0.0 }],
            grid: [h.res, h.grid_dim() as u32, self.layout.nx, self.layout.ny],
            frames: [k0 as u32 * g3, k1 as u32 * g3, (k0 == k1) as u32, 0],
            inv_tex: [1.0 / t[0] as f32, 1.0 / t[1] as f32, 1.0 / t[2] as f32, 0.0],
        }
    }

    fn ensure_target(&mut self, width: u32, height: u32, views: usize) -> Result<()> {
        let limits = self.ctx.device.limits();
        let px = width as u64 * height as u64;
        if px == 0 {
            bail!("cannot render an empty {}x{} image", width, height);
        }
        let bytes = px * 16;
        for (limit, max) in [
            (
                "max_storage_buffer_binding_size",
                limits.max_storage_buffer_binding_size,
            ),
            ("max_buffer_size", limits.max_buffer_size),
        ] {
            if bytes > max {
                return Err(LimitError {
                    limit,
                    needed: bytes,
                    max,
                    what: format!("a {}x{} image", width, height),
                }
                .into());
            }
        }
        let dim = limits.max_compute_workgroups_per_dimension as u64;
        if (width as u64).div_ceil(WG as u64) > dim || (height as u64).div_ceil(WG as u64) > dim {
            return Err(LimitError {
                limit: "max_compute_workgroups_per_dimension",
                needed: (width.max(height) as u64).div_ceil(WG as u64),
                max: dim,
                what: format!("a {}x{} image", width, height),
            }
            .into());
        }
        // two params buffers per view: the centre pass and the silhouette pass
        while self.params.len() < 2 * views {
            self.params
                .push(self.ctx.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("march params"),
                    size: std::mem::size_of::<Params>() as u64,
                    usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                }));
        }
        let fits = matches!(&self.target, Some(t) if t.width == width && t.height == height && t.bind_groups.len() >= 2 * views);
        if fits {
            return Ok(());
        }
        self.target = None;
        let device = self.ctx.device.clone();
        let target = self.ctx.scoped("allocating the output image", || {
            let mk = |label, size| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                })
            };
            let rgba = mk("march rgba", px * 16);
            let depth = mk("march depth", px * 4);
            let cover = mk("march cover", px * 4);
            let views_t: Vec<wgpu::TextureView> = self
                .tex
                .iter()
                .map(|t| t.create_view(&wgpu::TextureViewDescriptor::default()))
                .collect();
            let layout = self.pipeline.get_bind_group_layout(0);
            let bind_groups = self.params[..2 * views]
                .iter()
                .map(|p| {
                    let mut entries = vec![
                        wgpu::BindGroupEntry {
                            binding: 0,
                            resource: p.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 1,
                            resource: self.grid_buf.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: self.mlp_buf.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: rgba.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: depth.as_entire_binding(),
                        },
                        wgpu::BindGroupEntry {
                            binding: 8,
                            resource: cover.as_entire_binding(),
                        },
                    ];
                    for (k, v) in views_t.iter().enumerate() {
                        entries.push(wgpu::BindGroupEntry {
                            binding: 5 + k as u32,
                            resource: wgpu::BindingResource::TextureView(v),
                        });
                    }
                    if let Some(s) = &self.sampler {
                        entries.push(wgpu::BindGroupEntry {
                            binding: 7,
                            resource: wgpu::BindingResource::Sampler(s),
                        });
                    }
                    device.create_bind_group(&wgpu::BindGroupDescriptor {
                        label: Some("march bind group"),
                        layout: &layout,
                        entries: &entries,
                    })
                })
                .collect();
            Target {
                width,
                height,
                rgba,
                depth,
                _cover: cover,
                bind_groups,
            }
        })?;
        self.target = Some(target);
        Ok(())
    }

    /// Record the march of `views` (side by side in one `width` x `height` output) into
    /// `encoder`. The output buffer is `output_buffer()` afterwards.
    pub(crate) fn encode(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        width: u32,
        height: u32,
        views: &[View],
    ) -> Result<()> {
        self.ctx.check()?;
        for v in views {
            let c = &v.cam;
            if c.width == 0 || c.height == 0 || v.x0 + c.width > width || c.height > height {
                bail!(
                    "view {}x{} at x {} does not fit the {}x{} output",
                    c.width,
                    c.height,
                    v.x0,
                    width,
                    height
                );
            }
            if !(c.fx.is_finite() && c.fy.is_finite() && c.fx != 0.0 && c.fy != 0.0) {
                bail!(
                    "camera focal lengths must be finite and non-zero (fx {}, fy {})",
                    c.fx,
                    c.fy
                );
            }
        }
        self.ensure_target(width, height, views.len())?;
        // Silhouette pixels as the mean of side x side rays, as the field was trained, for
        // views whose pixels are about as coarse as the training views' (Header::pixel_rays_for);
        // side 1: the centre pass only.
        let sides: Vec<u32> = views
            .iter()
            .map(|v| snerf_geometry::silhouette::subpixel_side(self.header().pixel_rays_for(&v.cam) as usize) as u32)
            .collect();
        for (i, v) in views.iter().enumerate() {
            let mut p = self.params_for(v, width);
            self.ctx
                .queue
                .write_buffer(&self.params[2 * i], 0, bytemuck::bytes_of(&p));
            p.frames[3] = sides[i];
            self.ctx
                .queue
                .write_buffer(&self.params[2 * i + 1], 0, bytemuck::bytes_of(&p));
        }
        let target = self.target.as_ref().expect("target allocated above");
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("march"),
            timestamp_writes: None,
        });
        pass.set_pipeline(&self.pipeline);
        // every centre pass, then (each dispatch sees the writes of the ones before it) every
        // silhouette pass
        for k in [0, 1] {
            for (i, v) in views.iter().enumerate() {
                if k == 1 && sides[i] < 2 {
                    continue;
                }
                pass.set_bind_group(0, &target.bind_groups[2 * i + k], &[]);
                pass.dispatch_workgroups(v.cam.width.div_ceil(WG), v.cam.height.div_ceil(WG), 1);
            }
        }
        Ok(())
    }

    pub(crate) fn output_buffer(&self) -> Option<&wgpu::Buffer> {
        self.target.as_ref().map(|t| &t.rgba)
    }

    /// March `views` and wait for the GPU (no readback): the timed part of `bench_view`.
    pub fn render_wait(&mut self, width: u32, height: u32, views: &[View]) -> Result<Duration> {
        let t0 = Instant::now();
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("march"),
            });
        self.encode(&mut enc, width, height, views)?;
        self.ctx.queue.submit([enc.finish()]);
        self.ctx.wait()?;
        Ok(t0.elapsed())
    }

    /// March `views` side by side and read the image back.
    pub fn render_views(&mut self, width: u32, height: u32, views: &[View]) -> Result<Frame> {
        let mut enc = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("march"),
            });
        self.encode(&mut enc, width, height, views)?;
        let px = width as u64 * height as u64;
        let device = &self.ctx.device;
        let (rb_rgba, rb_depth) = self.ctx.scoped("allocating readback buffers", || {
            let mk = |size| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("readback"),
                    size,
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            (mk(px * 16), mk(px * 4))
        })?;
        let t = self.target.as_ref().expect("encode allocates the target");
        enc.copy_buffer_to_buffer(&t.rgba, 0, &rb_rgba, 0, px * 16);
        enc.copy_buffer_to_buffer(&t.depth, 0, &rb_depth, 0, px * 4);
        self.ctx.queue.submit([enc.finish()]);
        let rgba: Vec<f32> = read_buffer(&self.ctx, &rb_rgba)?;
        let depth: Vec<f32> = read_buffer(&self.ctx, &rb_depth)?;
        let mut f = Frame {
            width,
            height,
            rgb: Vec::with_capacity(px as usize * 3),
            depth,
            opacity: Vec::with_capacity(px as usize),
        };
        for p in rgba.chunks_exact(4) {
            f.rgb.extend_from_slice(&p[..3]);
            f.opacity.push(p[3]);
        }
        Ok(f)
    }

    /// One camera at `time` (seconds of the asset's time axis; ignored for static assets).
    pub fn render(&mut self, cam: &Camera, time: f32) -> Result<Frame> {
        self.render_views(
            cam.width,
            cam.height,
            &[View {
                cam: *cam,
                time,
                x0: 0,
            }],
        )
    }

    /// Left and right eye side by side (left in the left half), same time.
    pub fn render_stereo(&mut self, left: &Camera, right: &Camera, time: f32) -> Result<Frame> {
        let (w, h) = (left.width + right.width, left.height.max(right.height));
        self.render_views(
            w,
            h,
            &[
                View {
                    cam: *left,
                    time,
                    x0: 0,
                },
                View {
                    cam: *right,
                    time,
                    x0: left.width,
                },
            ],
        )
    }
}

/// f32 count of the shader's MLP layout (225 vec4).
pub const MLP_GPU_FLOATS: usize = 900;

/// The view MLP transposed for the shader: per layer, input-major rows of the 16 (or 3,
/// padded to 4) unit weights, then the biases: W1ᵀ [34][16], b1 [16], W2ᵀ [16][16],
/// b2 [16], W3ᵀ [16][4], b3 [4].
pub fn mlp_gpu_layout(m: &ViewMlp) -> Vec<f32> {
    use snerf_asset::mlp::{MLP_HIDDEN as H, MLP_IN as I, MLP_OUT as O};
    let mut v = Vec::with_capacity(MLP_GPU_FLOATS);
    let at = |w: &[f32], k: usize| w.get(k).copied().unwrap_or(0.0);
    for i in 0..I {
        for j in 0..H {
            v.push(at(&m.w1, j * I + i));
        }
    }
    v.extend((0..H).map(|j| at(&m.b1, j)));
    for i in 0..H {
        for j in 0..H {
            v.push(at(&m.w2, j * H + i));
        }
    }
    v.extend((0..H).map(|j| at(&m.b2, j)));
    for i in 0..H {
        for j in 0..4 {
            v.push(if j < O { at(&m.w3, j * H + i) } else { 0.0 });
        }
    }
    v.extend((0..4).map(|j| if j < O { at(&m.b3, j) } else { 0.0 }));
    debug_assert_eq!(v.len(), MLP_GPU_FLOATS);
    v
}

/// Map a buffer (after a submitted copy into it) and return its contents.
pub(crate) fn read_buffer<T: bytemuck::Pod>(
    ctx: &GpuContext,
    buf: &wgpu::Buffer,
) -> Result<Vec<T>> {
    let slice = buf.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    ctx.wait()?;
    rx.recv_timeout(Duration::from_secs(60))
        .map_err(|_| anyhow!("GPU readback never completed"))?
        .map_err(|e| anyhow!("GPU readback failed: {}", e))?;
    let data = {
        let view = slice
            .get_mapped_range()
            .map_err(|e| anyhow!("GPU readback failed: {:?}", e))?;
        bytemuck::cast_slice::<u8, T>(&view).to_vec()
    };
    buf.unmap();
    Ok(data)
}

/// The march shader variant an asset needs (`shader_variant`) and its source, composed by
/// `snerf_geometry::march::march_shader`, as `snerf serve` composes it for the web page.
pub fn shader_source(h: &Header, hardware_filter: bool) -> String {
    // The march constants come from snerf-geometry, so the shader cannot drift from the
    // CPU reference and the trainer.
    snerf_geometry::march::march_shader(shader_variant(h, hardware_filter))
}

/// Kind, keyframes, diffuse or not, block edge and atlas access of an asset's shader.
pub fn shader_variant(h: &Header, hardware_filter: bool) -> snerf_geometry::march::ShaderVariant {
    snerf_geometry::march::ShaderVariant {
        kind: h.kind.shader_index(),
        dynamic: h.num_frames() > 1,
        diffuse: h.diffuse,
        block: h.block,
        hardware_filter,
    }
}

fn build_pipeline(
    device: &wgpu::Device,
    h: &Header,
    hardware_filter: bool,
) -> wgpu::ComputePipeline {
    let src = shader_source(h, hardware_filter);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("march.wgsl"),
        source: wgpu::ShaderSource::Wgsl(src.into()),
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some("march"),
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    })
}

/// The voxel channels each atlas texture holds: one rg32uint texture all 8 channel bytes of
/// a voxel (a diffuse asset's r32uint the first 4); two rgba8unorm textures 4 each (a
/// diffuse asset's first alone).
#[allow(clippy::single_range_in_vec_init)]
fn texel_split(hardware_filter: bool, diffuse: bool) -> Vec<std::ops::Range<usize>> {
    match (hardware_filter, diffuse) {
        (true, false) => vec![0..4, 4..8],
        (_, true) => vec![0..4],
        (false, false) => vec![0..8],
    }
}

/// Sizes the GPU path relies on (a hand-built `Asset` may be inconsistent).
fn check_consistent(asset: &Asset) -> Result<()> {
    let h = &asset.header;
    let bb = asset.block_bytes() as u64;
    anyhow::ensure!(
        asset.atlas.len() as u64 == h.atlas_blocks as u64 * bb,
        "asset atlas has {} bytes, header claims {} blocks of {} bytes",
        asset.atlas.len(),
        h.atlas_blocks,
        bb
    );
    anyhow::ensure!(
        asset.present.len() == h.atlas_blocks as usize,
        "asset has {} present flags for {} blocks",
        asset.present.len(),
        h.atlas_blocks
    );
    anyhow::ensure!(
        asset.grids.len() == h.num_frames(),
        "asset has {} grids for {} frames",
        asset.grids.len(),
        h.num_frames()
    );
    Ok(())
}
