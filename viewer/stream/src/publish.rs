//! `snerf publish`: a baked asset as an immutable, content-addressed layout that any static
//! HTTP host or CDN serves (PUBLISH.md). No snerf process is in the path: the clients
//! (`cdn_client.rs`, the page's `ManifestSession`) read the manifest and order their own
//! fetches with the planner the server uses (`plan::order_blocks`).
//!
//! ```text
//! OUT/NAME/manifest.json   small, mutable: format version, asset, header, object list,
//!                          where every file chunk lives, the planner's block table
//! OUT/chunks/SHA256        immutable objects (name = SHA-256 of the bytes): whole file
//!                          chunks (tag, length, CRC, payload) packed up to `object_bytes`
//! OUT/index.html, app.js … the web viewer (opened as index.html?manifest=NAME/manifest.json)
//! ```
//!
//! Why objects of several file chunks: the writer emits one block (4–32 KB) per BLKS chunk,
//! and a request per block costs its HTTP headers (~0.3–0.5 KB each way) and a cache lookup;
//! packing spatial neighbours (Morton order of their cells, keyframe first) into objects of
//! `object_bytes` keeps the request overhead under 1% while a pose still picks the objects it
//! needs first (BENCH.md §8d measures the sizes). Whole objects rather than byte ranges: each
//! response is checked against its name (a range could only be checked against a CRC), and
//! an edge caches one key per object.
//!
//! Re-publishing writes only objects whose hash is not already there (a changed block changes
//! its object only: objects are cut by size along a fixed order, so equal-sized blocks keep
//! their boundaries), each atomically; the manifest is written last, atomically, so a host
//! never serves a manifest naming an object that is not there yet. Old objects are kept
//! (clients holding the previous manifest still find theirs).

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, ensure, Context, Result};
use bytes::Bytes;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use snerf_asset::chunk::{PREAMBLE_LEN, TAG_HEAD};
use snerf_asset::Header;

use crate::plan::{BlkEntry, ServedAsset};
use crate::proto::{to_hex, AssetInfo};

/// `manifest.json`'s `format`.
pub const MANIFEST_FORMAT: &str = "snerf-publish";
/// `manifest.json`'s `version`: a client refuses any other.
pub const MANIFEST_VERSION: u32 = 1;
/// Default object size (bytes): see BENCH.md §8d.
pub const DEFAULT_OBJECT_BYTES: u64 = 256 << 10;
/// Where objects live, relative to a manifest.
pub const OBJECTS_DIR: &str = "chunks";

/// One content-addressed object: `chunks/SHA256`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectRef {
    pub sha256: String,
    pub size: u64,
}

/// A BLKS chunk as the planner sees it (`plan::BlkEntry`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BlockRef {
    pub chunk: u32,
    pub centre: [f32; 3],
    pub radius: f32,
    pub frames: Vec<[u32; 2]>,
}

/// The web viewer's shaders for this asset, as objects (names are SHA-256s).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WebShaders {
    pub workgroup: u32,
    pub present_wgsl: String,
    pub march_wgsl: String,
    pub march_glsl: String,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub format: String,
    pub version: u32,
    /// Name, size, chunk count, SHA-256 and preamble of the file (as `snerf/1`'s welcome).
    pub asset: AssetInfo,
    /// The HEAD chunk's JSON.
    pub header: serde_json::Value,
    /// The asset's view (`header.view`) and floor, for clients that place the scene first.
    pub view: Option<serde_json::Value>,
    pub floor: Option<f32>,
    /// Objects' folder relative to the manifest's URL.
    pub objects_base: String,
    /// Target object size the layout was cut with.
    pub object_bytes: u64,
    pub objects: Vec<ObjectRef>,
    /// For every file chunk by index: [object, offset in it, length] (the chunk's whole
    /// bytes: tag, length, CRC, payload).
    pub chunks: Vec<[u64; 3]>,
    /// HEAD, VMLP and GRID chunks (sent first), and END.
    pub meta: Vec<u32>,
    pub end: u32,
    /// Grid centre in the world (the planner's origin without a pose) and the block table.
    pub origin: [f32; 3],
    pub blocks: Vec<BlockRef>,
    pub web: Option<WebShaders>,
}

impl Manifest {
    /// Parse and check a manifest's bytes; `what` names it in errors (file or URL).
    pub fn parse(bytes: &[u8], what: &str) -> Result<Manifest> {
        let v: serde_json::Value = serde_json::from_slice(bytes)
            .map_err(|e| anyhow!("{what}: not a snerf manifest (JSON: {e})"))?;
        let format = v.get("format").and_then(|f| f.as_str()).unwrap_or("");
        ensure!(
            format == MANIFEST_FORMAT,
            "{what}: not a snerf manifest (format {format:?}, expected {MANIFEST_FORMAT:?})"
        );
        let version = v.get("version").and_then(|f| f.as_u64()).unwrap_or(0);
        ensure!(
            version == MANIFEST_VERSION as u64,
            "{what}: manifest format version {version}; this snerf reads version {MANIFEST_VERSION} (publish again, or update snerf)"
        );
        let m: Manifest =
            serde_json::from_value(v).map_err(|e| anyhow!("{what}: malformed manifest: {e}"))?;
        m.check().map_err(|e| anyhow!("{what}: {e:#}"))?;
        Ok(m)
    }

    /// Every reference inside the manifest is in range, so no client indexes out of bounds.
    fn check(&self) -> Result<()> {
        let n = self.asset.chunks as usize;
        ensure!(
            self.chunks.len() == n && n >= 2,
            "{} chunk entries for {} chunks",
            self.chunks.len(),
            n
        );
        ensure!(
            self.asset.sha256.len() == 64 && self.asset.preamble.len() == 2 * PREAMBLE_LEN,
            "bad asset hashes"
        );
        for o in &self.objects {
            ensure!(
                o.sha256.len() == 64 && o.sha256.bytes().all(|c| c.is_ascii_hexdigit()),
                "bad object name {:?}",
                o.sha256
            );
        }
        let mut total = PREAMBLE_LEN as u64;
        for (i, c) in self.chunks.iter().enumerate() {
            let o = self
                .objects
                .get(c[0] as usize)
                .ok_or_else(|| anyhow!("chunk {i}: no object {}", c[0]))?;
            ensure!(
                c[2] >= 12 && c[1].checked_add(c[2]).is_some_and(|e| e <= o.size),
                "chunk {i}: outside its object"
            );
            total += c[2];
        }
        ensure!(
            total == self.asset.size,
            "chunks add up to {total} bytes, the asset has {}",
            self.asset.size
        );
        ensure!(
            (self.end as usize) < n && self.meta.iter().all(|&i| (i as usize) < n),
            "meta chunk out of range"
        );
        ensure!(
            self.blocks.iter().all(|b| (b.chunk as usize) < n),
            "block chunk out of range"
        );
        ensure!(
            !self.objects_base.contains("://") && !self.objects_base.starts_with('/'),
            "objects_base must be relative"
        );
        Ok(())
    }

    /// The planner's view of the asset (no bytes): `plan::order_blocks` runs on it as on a
    /// served file, so a published scene's clients order blocks exactly as the server does.
    pub fn planner(&self) -> Result<ServedAsset> {
        let header: Header =
            serde_json::from_value(self.header.clone()).context("manifest header")?;
        header.validate().context("manifest header")?;
        let mut ranges = Vec::with_capacity(self.chunks.len());
        let mut pos = PREAMBLE_LEN;
        for c in &self.chunks {
            ranges.push(pos..pos + c[2] as usize);
            pos += c[2] as usize;
        }
        Ok(ServedAsset {
            name: self.asset.name.clone(),
            path: PathBuf::from(&self.asset.name),
            bytes: Bytes::new(),
            sha256: self.asset.sha256.clone(),
            header,
            ranges,
            meta: self.meta.clone(),
            blks: self
                .blocks
                .iter()
                .map(|b| BlkEntry {
                    chunk: b.chunk,
                    centre: b.centre,
                    radius: b.radius,
                    frames: b.frames.iter().map(|f| (f[0], f[1])).collect(),
                })
                .collect(),
            end: self.end,
            styles: None,
            colour: None,
            origin: self.origin,
        })
    }

    /// Objects to fetch, most urgent first: those holding HEAD, VMLP, GRIDs and END, then
    /// each object at the place of its most urgent block in `plan::order_blocks`' order for
    /// `pose`. `held[o]`: object o is already here (left out).
    pub fn object_order(
        &self,
        planner: &ServedAsset,
        pose: Option<crate::proto::Pose>,
        held: &[bool],
    ) -> Vec<usize> {
        let mut seen = held.to_vec();
        seen.resize(self.objects.len(), false);
        let mut out = Vec::new();
        let mut take = |o: usize, out: &mut Vec<usize>| {
            if !seen[o] {
                seen[o] = true;
                out.push(o);
            }
        };
        for &c in self.meta.iter().chain(std::iter::once(&self.end)) {
            take(self.chunks[c as usize][0] as usize, &mut out);
        }
        let mut blocks: Vec<u32> = (0..planner.blks.len() as u32).collect();
        crate::plan::order_blocks(planner, &mut blocks, pose);
        for &b in blocks.iter().rev() {
            take(
                self.chunks[planner.blks[b as usize].chunk as usize][0] as usize,
                &mut out,
            );
        }
        // Objects holding no chunk (none are written) would be left: nothing to fetch.
        out
    }

    /// The file's chunks cut out of verified objects, in file order, after the preamble.
    pub fn assemble(&self, objects: &[Vec<u8>]) -> Result<Vec<u8>> {
        let pre = crate::proto::from_hex(&self.asset.preamble).context("manifest preamble")?;
        let mut file = Vec::with_capacity(self.asset.size as usize);
        file.extend_from_slice(&pre);
        for c in &self.chunks {
            let o = &objects[c[0] as usize];
            file.extend_from_slice(&o[c[1] as usize..(c[1] + c[2]) as usize]);
        }
        let got = to_hex(&Sha256::digest(&file));
        ensure!(
            got == self.asset.sha256,
            "the assembled file's SHA-256 is {got}, the manifest says {}",
            self.asset.sha256
        );
        Ok(file)
    }
}

/// What `publish` did.
#[derive(Clone, Debug, Serialize)]
pub struct Published {
    pub name: String,
    pub manifest: PathBuf,
    pub asset_bytes: u64,
    pub manifest_bytes: u64,
    pub objects: usize,
    pub objects_written: usize,
    pub bytes_written: u64,
    pub objects_reused: usize,
}

#[derive(Clone, Debug)]
pub struct PublishOptions {
    pub object_bytes: u64,
    /// Also write the web viewer (page files at OUT/, shaders as objects).
    pub web: bool,
}

impl Default for PublishOptions {
    fn default() -> Self {
        PublishOptions {
            object_bytes: DEFAULT_OBJECT_BYTES,
            web: true,
        }
    }
}

/// Publish one asset file into `out` (created if needed).
pub fn publish(asset: &Path, out: &Path, opts: &PublishOptions) -> Result<Published> {
    ensure!(
        opts.object_bytes >= 4096,
        "--object-kb: objects of at least 4 KiB"
    );
    let name = crate::shared::asset_name(asset);
    ensure!(
        crate::proto::valid_asset_name(&name),
        "{}: the asset name {name:?} must be [A-Za-z0-9._-], not starting with '.'",
        asset.display()
    );
    let a = ServedAsset::load(&name, asset)?;
    let objects_dir = out.join(OBJECTS_DIR);
    std::fs::create_dir_all(&objects_dir)
        .with_context(|| format!("{}: cannot create", objects_dir.display()))?;
    let mut st = Store {
        dir: objects_dir,
        written: 0,
        bytes: 0,
        reused: 0,
    };

    // Meta objects (HEAD, VMLP, GRIDs, END), then blocks in spatial order, keyframe first.
    let mut metas: Vec<u32> = a.meta.clone();
    metas.push(a.end);
    let order = spatial_order(&a);
    let groups: Vec<Vec<u32>> = pack(&a, &metas, opts.object_bytes)
        .into_iter()
        .chain(pack(&a, &order, opts.object_bytes))
        .collect();
    let mut chunks = vec![[0u64; 3]; a.chunk_count() as usize];
    let mut objects = Vec::with_capacity(groups.len());
    for g in &groups {
        let mut bytes = Vec::new();
        for &c in g {
            let r = &a.ranges[c as usize];
            chunks[c as usize] = [objects.len() as u64, bytes.len() as u64, r.len() as u64];
            bytes.extend_from_slice(&a.bytes[r.clone()]);
        }
        objects.push(st.put(&bytes)?);
    }
    let web = if opts.web {
        Some(write_web(out, &a.header, &mut st)?)
    } else {
        None
    };
    let head_range = &a.ranges[a.meta[0] as usize];
    ensure!(
        a.bytes[head_range.start..head_range.start + 4] == TAG_HEAD,
        "first chunk is not HEAD"
    );
    let header: serde_json::Value =
        serde_json::from_slice(&a.bytes[head_range.start + 12..head_range.end])
            .context("HEAD JSON")?;
    let m = Manifest {
        format: MANIFEST_FORMAT.into(),
        version: MANIFEST_VERSION,
        asset: a.info(),
        view: header.get("view").cloned().filter(|v| !v.is_null()),
        floor: header
            .get("floor")
            .and_then(|f| f.as_f64())
            .map(|f| f as f32),
        header,
        objects_base: format!("../{OBJECTS_DIR}/"),
        object_bytes: opts.object_bytes,
        objects,
        chunks,
        meta: a.meta.clone(),
        end: a.end,
        origin: a.origin,
        blocks: a
            .blks
            .iter()
            .map(|b| BlockRef {
                chunk: b.chunk,
                centre: b.centre,
                radius: b.radius,
                frames: b.frames.iter().map(|f| [f.0, f.1]).collect(),
            })
            .collect(),
        web,
    };
    let body = serde_json::to_vec(&m)?;
    // The written manifest must read back (and plan) as a client will read it.
    Manifest::parse(&body, "manifest")?.planner()?;
    let dir = out.join(&name);
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let manifest = dir.join("manifest.json");
    snerf_asset::atomic::write_atomic(&manifest, &body)
        .with_context(|| format!("{}: cannot write", manifest.display()))?;
    Ok(Published {
        name,
        manifest,
        asset_bytes: a.bytes.len() as u64,
        manifest_bytes: body.len() as u64,
        objects: groups.len(),
        objects_written: st.written,
        bytes_written: st.bytes,
        objects_reused: st.reused,
    })
}

/// The object folder: writes an object only when no file of that name holds its bytes.
struct Store {
    dir: PathBuf,
    written: usize,
    bytes: u64,
    reused: usize,
}

impl Store {
    fn put(&mut self, bytes: &[u8]) -> Result<ObjectRef> {
        let sha = to_hex(&Sha256::digest(bytes));
        let path = self.dir.join(&sha);
        // An existing object is trusted only if its bytes still hash to its name (a damaged
        // copy is replaced, not kept forever).
        let ok = std::fs::read(&path)
            .map(|b| b.len() == bytes.len() && to_hex(&Sha256::digest(&b)) == sha)
            .unwrap_or(false);
        if ok {
            self.reused += 1;
        } else {
            snerf_asset::atomic::write_atomic(&path, bytes)
                .with_context(|| format!("{}: cannot write", path.display()))?;
            self.written += 1;
            self.bytes += bytes.len() as u64;
        }
        Ok(ObjectRef {
            sha256: sha,
            size: bytes.len() as u64,
        })
    }
}

/// Consecutive chunks of `order` packed into groups of at most `target` bytes (a chunk larger
/// than that is a group alone).
fn pack(a: &ServedAsset, order: &[u32], target: u64) -> Vec<Vec<u32>> {
    let mut out: Vec<Vec<u32>> = Vec::new();
    let mut size = 0u64;
    for &c in order {
        let n = a.ranges[c as usize].len() as u64;
        match out.last_mut() {
            Some(g) if size + n <= target => {
                g.push(c);
                size += n;
            }
            _ => {
                out.push(vec![c]);
                size = n;
            }
        }
    }
    out
}

/// BLKS chunks by first keyframe, then the Morton code of their place in the grid's box:
/// neighbours share objects, so an object is wanted early or late as a whole.
fn spatial_order(a: &ServedAsset) -> Vec<u32> {
    let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
    for b in &a.blks {
        for i in 0..3 {
            lo[i] = lo[i].min(b.centre[i]);
            hi[i] = hi[i].max(b.centre[i]);
        }
    }
    let q = |b: &BlkEntry| -> u64 {
        let mut code = 0u64;
        let c: Vec<u64> = (0..3)
            .map(|i| {
                let s = if hi[i] > lo[i] {
                    (b.centre[i] - lo[i]) / (hi[i] - lo[i])
                } else {
                    0.0
                };
                (s.clamp(0.0, 1.0) * 1023.0) as u64
            })
            .collect();
        for bit in (0..10).rev() {
            for v in &c {
                code = code << 1 | (v >> bit & 1);
            }
        }
        code
    };
    let mut keyed: Vec<((u32, u64, u32), u32)> = a
        .blks
        .iter()
        .map(|b| {
            (
                (b.frames.first().map_or(0, |f| f.0), q(b), b.chunk),
                b.chunk,
            )
        })
        .collect();
    keyed.sort_unstable();
    keyed.into_iter().map(|k| k.1).collect()
}

/// The web viewer: page files at OUT/ (replaced when they differ), the asset's shaders as
/// objects.
fn write_web(out: &Path, h: &Header, st: &mut Store) -> Result<WebShaders> {
    // The page's own files by relative paths, so a scene published under a sub-path
    // (https://host/scenes/) finds them.
    let index = crate::page::INDEX_HTML
        .replace("\"/app.css\"", "\"app.css\"")
        .replace("\"/app.js\"", "\"app.js\"");
    for (file, text) in [
        ("index.html", index.as_str()),
        ("app.js", crate::page::APP_JS),
        ("xr.js", crate::page::XR_JS),
        ("app.css", crate::page::APP_CSS),
    ] {
        let p = out.join(file);
        if std::fs::read(&p).ok().as_deref() != Some(text.as_bytes()) {
            snerf_asset::atomic::write_atomic(&p, text.as_bytes())
                .with_context(|| format!("{}: cannot write", p.display()))?;
        }
    }
    let kind = match h.kind {
        snerf_asset::Kind::Object => 0,
        snerf_asset::Kind::Forward => 1,
        snerf_asset::Kind::Unbounded => 2,
    };
    let q = format!(
        "kind={kind}&dynamic={}&diffuse={}&block={}",
        (h.num_frames() > 1) as u8,
        h.diffuse as u8,
        h.block
    );
    let variant = crate::page::shader_query(&q).ok_or_else(|| anyhow!("no web shader for {q}"))?;
    let glsl = crate::glsl::march_glsl(variant)
        .map_err(|e| anyhow!("translating the march to GLSL: {e:#}"))?;
    Ok(WebShaders {
        workgroup: snerf_geometry::march::WORKGROUP,
        present_wgsl: st
            .put(snerf_geometry::march::PRESENT_WGSL.as_bytes())?
            .sha256,
        march_wgsl: st
            .put(snerf_geometry::march::march_shader(variant).as_bytes())?
            .sha256,
        march_glsl: st.put(glsl.to_json().as_bytes())?.sha256,
    })
}

/// Check that `dir` holds what a manifest names (every object present, hashing to its name).
pub fn verify_dir(manifest: &Path) -> Result<Manifest> {
    let bytes =
        std::fs::read(manifest).with_context(|| format!("{}: cannot read", manifest.display()))?;
    let m = Manifest::parse(&bytes, &manifest.display().to_string())?;
    let base = manifest
        .parent()
        .unwrap_or(Path::new("."))
        .join(&m.objects_base);
    for o in &m.objects {
        let p = base.join(&o.sha256);
        let b = std::fs::read(&p).with_context(|| format!("{}: missing", p.display()))?;
        if to_hex(&Sha256::digest(&b)) != o.sha256 {
            bail!("{}: bytes do not hash to the name", p.display());
        }
    }
    Ok(m)
}
