// snerf web viewer: lists the served assets, streams one over WebTransport (`snerf/1`, see
// viewer/stream/PROTOCOL.md) and ray-marches it with WebGPU. The march is the compute shader
// of shaders/march.wgsl, composed by the server exactly as the native viewer composes it
// (GET /march.wgsl); this file only does what the native viewer's host code does: parse the
// chunks, place blocks in the atlas texture, pack the grid, lay out the MLP and the params.
//
// URL fragment (never sent to the server): token=HEX (required), asset=NAME (stream it right
// away), cam=JSON ({c2w:[[4],[4],[4]], fx, fy, cx, cy, width, height}: a fixed camera),
// time=T (playback time of a 4D asset).

const EMPTY = 0xffffffff;
const $ = (id) => document.getElementById(id);
const frag = new URLSearchParams(location.hash.slice(1));
const token = frag.get('token') || '';
const fixedCam = frag.get('cam') ? JSON.parse(frag.get('cam')) : null;

// What the page reports (read by tests and the stats overlay).
const report = (window.snerf = {
  state: 'starting', error: null, listing: null, asset: null, sha256: null, bytes: 0,
  chunks: 0, blocks: 0, firstFrameMs: null, frames: 0, frame: null, firstFrame: null,
  adapter: null,
});

function setStatus(s) { $('status').textContent = s; }
function fail(e) {
  report.error = String(e && e.message ? e.message : e);
  report.state = 'error';
  setStatus('error: ' + report.error);
}

// ---- bytes ----
const te = new TextEncoder();
const td = new TextDecoder();
const u32 = (b, o) => (b[o] | (b[o + 1] << 8) | (b[o + 2] << 16) | (b[o + 3] << 24)) >>> 0;
const hex = (b) => Array.from(b, (x) => x.toString(16).padStart(2, '0')).join('');
const unhex = (s) => new Uint8Array(s.match(/../g).map((x) => parseInt(x, 16)));
const CRC = (() => {
  const t = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    t[n] = c >>> 0;
  }
  return t;
})();
function crc32(b) {
  let c = 0xffffffff;
  for (let i = 0; i < b.length; i++) c = CRC[(c ^ b[i]) & 255] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}
function frame(msg) {
  const j = te.encode(JSON.stringify(msg));
  const out = new Uint8Array(4 + j.length);
  new DataView(out.buffer).setUint32(0, j.length, true);
  out.set(j, 4);
  return out;
}

// Reads exact byte counts from a WebTransport stream.
class Reader {
  constructor(readable) { this.r = readable.getReader(); this.buf = new Uint8Array(0); this.done = false; }
  async fill(n) {
    while (this.buf.length < n && !this.done) {
      const { value, done } = await this.r.read();
      if (done) { this.done = true; break; }
      if (this.buf.length === 0) this.buf = value;
      else { const b = new Uint8Array(this.buf.length + value.length); b.set(this.buf); b.set(value, this.buf.length); this.buf = b; }
    }
    return this.buf.length >= n;
  }
  // n bytes, or null at a clean end of stream before any of them.
  async take(n) {
    if (!(await this.fill(n))) {
      if (this.buf.length === 0) return null;
      throw new Error('stream ended inside a record');
    }
    const out = this.buf.subarray(0, n);
    this.buf = this.buf.subarray(n);
    return out;
  }
}

async function readMsg(rd) {
  const l = await rd.take(4);
  if (!l) throw new Error('the server closed the control stream');
  const n = u32(l, 0);
  if (n > 4 << 20) throw new Error('control message too large');
  return JSON.parse(td.decode(await rd.take(n)));
}

// ---- WebTransport ----
let config = null;
async function connect(hello) {
  const opts = {};
  if (config.cert_hash) opts.serverCertificateHashes = [{ algorithm: 'sha-256', value: unhex(config.cert_hash) }];
  const wt = new WebTransport(config.webtransport, opts);
  await wt.ready;
  const bidi = await wt.createBidirectionalStream();
  const writer = bidi.writable.getWriter();
  const ctl = new Reader(bidi.readable);
  await writer.write(frame(hello));
  return { wt, writer, ctl };
}

async function listAssets() {
  const { wt, writer, ctl } = await connect({ type: 'hello', version: 1, token, asset: null });
  const welcome = await readMsg(ctl);
  if (welcome.type !== 'welcome') throw new Error('unexpected ' + welcome.type);
  await writer.write(frame({ type: 'list' }));
  const listing = await readMsg(ctl);
  wt.close({ closeCode: 0, reason: 'done' });
  return listing.assets;
}

// ---- math (snerf_geometry::camera) ----
const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scl = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const norm = (a) => Math.hypot(a[0], a[1], a[2]);
const unit = (a) => scl(a, 1 / norm(a));
function lookAt(eye, target, up) {
  const back = unit(sub(eye, target));
  let right = cross(up, back);
  if (norm(right) < 1e-6) right = cross([1, 0, 0], back);
  right = unit(right);
  const u = cross(back, right);
  return [0, 1, 2].map((i) => [right[i], u[i], back[i], eye[i]]);
}
// model = scale * rot * (world - center): world direction of a model direction.
const dirToWorld = (s, d) => [0, 1, 2].map((j) => s.rot[0][j] * d[0] + s.rot[1][j] * d[1] + s.rot[2][j] * d[2]);

// The scene's orbit (Header::orbit): centre, up, start direction, radius, elevation.
function orbitOf(h) {
  const v = h.view;
  if (v && v.path === 'around') return { center: v.center, up: v.up, start: v.start, radius: v.radius, elevation: v.elevation };
  if (v && v.path === 'ellipse') {
    const d = sub(v.center, v.target);
    const r = norm(d);
    const start = unit(sub(d, scl(v.up, dot(d, v.up))));
    return { center: v.target, up: v.up, start, radius: r, elevation: Math.asin(Math.max(-1, Math.min(1, dot(d, v.up) / r))) };
  }
  const s = h.space;
  return { center: s.center, up: dirToWorld(s, [0, 1, 0]), start: dirToWorld(s, [0, 0, 1]), radius: 3 / s.scale, elevation: (30 * Math.PI) / 180 };
}

// ---- the renderer (host side of viewer/src/gpu.rs) ----
class Renderer {
  constructor(device, h, shader, wg) {
    this.device = device;
    this.h = h;
    this.wg = wg;
    this.g = h.res / h.block;
    this.g3 = this.g ** 3;
    this.frames = h.frames ? h.frames.length : 1;
    this.edge = h.block + 2;
    this.layout = planAtlas(h.atlas_blocks, this.edge, device.limits.maxTextureDimension3D);
    const t = this.texels();
    this.atlas = device.createTexture({ size: t, dimension: '3d', format: 'rg32uint', usage: GPUTextureUsage.TEXTURE_BINDING | GPUTextureUsage.COPY_DST });
    this.gridBuf = device.createBuffer({ size: Math.max(4, this.g3 * this.frames * 4), usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_DST });
    this.mlpBuf = device.createBuffer({ size: 900 * 4, usage: GPUBufferUsage.UNIFORM | GPUBufferUsage.COPY_DST });
    this.paramBuf = device.createBuffer({ size: 256, usage: GPUBufferUsage.UNIFORM | GPUBufferUsage.COPY_DST });
    this.pipeline = device.createComputePipeline({ layout: 'auto', compute: { module: device.createShaderModule({ code: shader }), entryPoint: 'main' } });
    this.grids = new Array(this.frames).fill(null);
    this.present = new Uint8Array(h.atlas_blocks);
    this.gridDirty = true;
    this.target = null;
  }
  texels() { const l = this.layout; return [l.nx * l.edge, l.ny * l.edge, l.nz * l.edge]; }
  packed(b) { const l = this.layout; return (b % l.nx) | ((Math.floor(b / l.nx) % l.ny) << 10) | (Math.floor(b / (l.nx * l.ny)) << 20); }
  origin(b) { const l = this.layout; return [(b % l.nx) * l.edge, (Math.floor(b / l.nx) % l.ny) * l.edge, Math.floor(b / (l.nx * l.ny)) * l.edge]; }
  setMlp(payload) {
    const f = new Float32Array(payload.slice().buffer, 0, 883);
    const I = 34, H = 16, O = 3;
    const W1 = 0, B1 = H * I, W2 = B1 + H, B2 = W2 + H * H, W3 = B2 + H, B3 = W3 + O * H;
    const v = new Float32Array(900);
    let k = 0;
    for (let i = 0; i < I; i++) for (let j = 0; j < H; j++) v[k++] = f[W1 + j * I + i];
    for (let j = 0; j < H; j++) v[k++] = f[B1 + j];
    for (let i = 0; i < H; i++) for (let j = 0; j < H; j++) v[k++] = f[W2 + j * H + i];
    for (let j = 0; j < H; j++) v[k++] = f[B2 + j];
    for (let i = 0; i < H; i++) for (let j = 0; j < 4; j++) v[k++] = j < O ? f[W3 + j * H + i] : 0;
    for (let j = 0; j < 4; j++) v[k++] = j < O ? f[B3 + j] : 0;
    this.device.queue.writeBuffer(this.mlpBuf, 0, v);
  }
  setGrid(frameIndex, entries) { this.grids[frameIndex] = entries; this.gridDirty = true; }
  // `data`: `count` blocks of (block+2)^3 voxels x 8 bytes: one rg32uint texel per voxel.
  setBlocks(first, count, data) {
    const e = this.edge, bb = e * e * e * 8;
    for (let k = 0; k < count; k++) {
      const b = first + k;
      this.device.queue.writeTexture({ texture: this.atlas, origin: this.origin(b) }, data.subarray(k * bb, (k + 1) * bb), { bytesPerRow: e * 8, rowsPerImage: e }, [e, e, e]);
      this.present[b] = 1;
    }
    this.gridDirty = true;
  }
  uploadGrid() {
    const host = new Uint32Array(this.g3 * this.frames).fill(EMPTY);
    for (let f = 0; f < this.frames; f++) {
      const g = this.grids[f];
      if (!g) continue;
      for (let i = 0; i < this.g3; i++) {
        const e = g[i];
        if (e !== EMPTY && this.present[e]) host[f * this.g3 + i] = this.packed(e);
      }
    }
    this.device.queue.writeBuffer(this.gridBuf, 0, host);
    this.gridDirty = false;
  }
  params(cam, time) {
    const h = this.h, s = h.space;
    const [k0, k1, w] = timeSlot(h.frames || [], time);
    const n = s.ndc || { fx: 1, fy: 1, width: 1, height: 1, near: 1, xy_extent: 1 };
    const t = this.texels();
    const b = new ArrayBuffer(256), f = new Float32Array(b), u = new Uint32Array(b);
    f.set(cam.c2w[0], 0); f.set(cam.c2w[1], 4); f.set(cam.c2w[2], 8);
    f.set([cam.fx, cam.fy, cam.cx, cam.cy], 12);
    u.set([cam.width, cam.height, 0, cam.width], 16);
    f.set(s.rot[0], 20); f.set(s.rot[1], 24); f.set(s.rot[2], 28);
    f.set([s.center[0], s.center[1], s.center[2], s.scale], 32);
    f.set([n.fx, n.fy, n.width, n.height], 36);
    f.set([n.near, n.xy_extent, h.march.step, h.march.t_terminate], 40);
    f.set([h.density.logit_min, h.density.logit_max, w, 0], 44);
    f.set([h.background[0], h.background[1], h.background[2], 0], 48);
    u.set([h.res, this.g, this.layout.nx, this.layout.ny], 52);
    u.set([k0 * this.g3, k1 * this.g3, k0 === k1 ? 1 : 0, 0], 56);
    f.set([1 / t[0], 1 / t[1], 1 / t[2], 0], 60);
    return b;
  }
  // March one image and read it back: Float32Array of width*height RGBA (A = opacity).
  async render(cam, time) {
    const d = this.device, px = cam.width * cam.height;
    if (this.gridDirty) this.uploadGrid();
    if (!this.target || this.target.w !== cam.width || this.target.h !== cam.height) {
      const rgba = d.createBuffer({ size: px * 16, usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_SRC });
      const depth = d.createBuffer({ size: px * 4, usage: GPUBufferUsage.STORAGE });
      const readback = d.createBuffer({ size: px * 16, usage: GPUBufferUsage.MAP_READ | GPUBufferUsage.COPY_DST });
      const bind = d.createBindGroup({
        layout: this.pipeline.getBindGroupLayout(0),
        entries: [
          { binding: 0, resource: { buffer: this.paramBuf } },
          { binding: 1, resource: { buffer: this.gridBuf } },
          { binding: 2, resource: { buffer: this.mlpBuf } },
          { binding: 3, resource: { buffer: rgba } },
          { binding: 4, resource: { buffer: depth } },
          { binding: 5, resource: this.atlas.createView() },
        ],
      });
      this.target = { w: cam.width, h: cam.height, rgba, depth, readback, bind };
    }
    d.queue.writeBuffer(this.paramBuf, 0, this.params(cam, time));
    const enc = d.createCommandEncoder();
    const pass = enc.beginComputePass();
    pass.setPipeline(this.pipeline);
    pass.setBindGroup(0, this.target.bind);
    pass.dispatchWorkgroups(Math.ceil(cam.width / this.wg), Math.ceil(cam.height / this.wg));
    pass.end();
    enc.copyBufferToBuffer(this.target.rgba, 0, this.target.readback, 0, px * 16);
    d.queue.submit([enc.finish()]);
    await this.target.readback.mapAsync(GPUMapMode.READ);
    const out = new Float32Array(this.target.readback.getMappedRange().slice(0));
    this.target.readback.unmap();
    return out;
  }
}

// AtlasLayout::plan (viewer/src/gpu.rs).
function planAtlas(blocks, edge, maxDim) {
  const n = Math.max(1, blocks);
  let cap = Math.floor(maxDim / edge);
  if (cap === 0 || cap ** 3 < n) throw new Error(`the atlas (${blocks} blocks of ${edge}^3) does not fit this GPU's 3D textures`);
  cap = Math.min(cap, 1024);
  let nx = Math.min(Math.max(Math.ceil(Math.cbrt(n)), 1), cap);
  let ny = Math.min(Math.max(Math.ceil(Math.sqrt(Math.ceil(n / nx))), 1), cap);
  let nz = Math.ceil(n / (nx * ny));
  if (nz > cap) { nx = cap; ny = cap; nz = Math.ceil(n / (cap * cap)); }
  return { edge, nx, ny, nz };
}

// snerf_geometry::time_slot.
function timeSlot(frames, t) {
  if (frames.length === 0 || !(t > frames[0].time)) return [0, 0, 0];
  const last = frames.length - 1;
  if (t >= frames[last].time) return [last, last, 0];
  let k = 0;
  while (k < frames.length && frames[k].time <= t) k++;
  const a = frames[k - 1].time, b = frames[k].time;
  const w = b > a ? Math.min(1, Math.max(0, Math.fround((Math.fround(t - a)) / Math.fround(b - a)))) : 0;
  return [k - 1, k, w];
}

// ---- streaming one asset ----
async function stream(name, device, wg) {
  const t0 = performance.now();
  const view = { yaw: 0, pitch: null, radius: null };
  let time = frag.has('time') ? parseFloat(frag.get('time')) : 0;
  let h = null, r = null, orbit = null;
  const chunks = [];
  let finish, abort;
  const complete = new Promise((res, rej) => { finish = res; abort = rej; });
  let dirty = false, rendering = false, seq = 0, dgram = null;

  function camera() {
    if (fixedCam) return fixedCam;
    const o = orbit;
    const el = view.pitch ?? o.elevation;
    const rad = view.radius ?? o.radius;
    const side = cross(o.up, o.start);
    const horiz = add(scl(o.start, Math.cos(view.yaw)), scl(side, Math.sin(view.yaw)));
    const dir = add(scl(horiz, Math.cos(el)), scl(o.up, Math.sin(el)));
    const c2w = lookAt(add(o.center, scl(dir, rad)), o.center, o.up);
    const cv = $('canvas');
    const f = (0.5 * cv.height) / Math.tan((0.5 * 40 * Math.PI) / 180);
    return { c2w, fx: f, fy: f, cx: cv.width / 2, cy: cv.height / 2, width: cv.width, height: cv.height };
  }
  function poseBytes() {
    const c = camera();
    const b = new ArrayBuffer(40), dv = new DataView(b);
    dv.setUint8(0, 0x53); dv.setUint8(1, 0x50); dv.setUint8(2, 1); dv.setUint8(3, 0);
    dv.setUint32(4, ++seq, true);
    const fwd = [-c.c2w[0][2], -c.c2w[1][2], -c.c2w[2][2]];
    [c.c2w[0][3], c.c2w[1][3], c.c2w[2][3], ...fwd, time, 0].forEach((v, i) => dv.setFloat32(8 + 4 * i, v, true));
    return new Uint8Array(b);
  }
  function sendPose() { if (dgram) dgram.write(poseBytes()).catch(() => {}); }

  const hello = { type: 'hello', version: 1, token, asset: name, have: [] };
  const { wt, ctl } = await connect(hello);
  const welcome = await readMsg(ctl);
  if (welcome.type !== 'welcome' || !welcome.asset) throw new Error('no asset in the welcome');
  const info = welcome.asset;
  report.asset = info;
  report.state = 'streaming';
  dgram = wt.datagrams.writable.getWriter();
  const poseTimer = setInterval(sendPose, 250);

  async function draw() {
    if (rendering || !r || !dirty) return;
    rendering = true;
    dirty = false;
    try {
      const cam = camera();
      const ts = performance.now();
      // What this frame shows: the blocks uploaded before it was submitted.
      const blocks = report.blocks, complete = report.chunks === info.chunks;
      const rgba = await r.render(cam, time);
      blit(rgba, cam.width, cam.height);
      report.frames++;
      const ms = performance.now() - ts;
      if (report.firstFrameMs === null) {
        report.firstFrameMs = performance.now() - t0;
        report.firstFrame = { width: cam.width, height: cam.height, blocks, complete };
      }
      report.lastRender = { rgba, width: cam.width, height: cam.height, complete };
      stats(ms);
    } catch (e) { fail(e); }
    rendering = false;
    if (dirty) requestAnimationFrame(draw);
  }
  const redraw = () => { dirty = true; requestAnimationFrame(draw); };

  function blit(rgba, w, hgt) {
    const cv = $('canvas');
    if (cv.width !== w || cv.height !== hgt) { cv.width = w; cv.height = hgt; }
    const img = new ImageData(w, hgt);
    for (let i = 0; i < w * hgt; i++) {
      for (let c = 0; c < 3; c++) img.data[4 * i + c] = Math.round(Math.min(1, Math.max(0, rgba[4 * i + c])) * 255);
      img.data[4 * i + 3] = 255;
    }
    cv.getContext('2d').putImageData(img, 0, 0);
  }
  function stats(ms) {
    $('stats').textContent =
      `${(1000 / Math.max(ms, 0.01)).toFixed(1)} fps (${ms.toFixed(1)} ms)\n` +
      `blocks ${report.blocks}/${h ? h.atlas_blocks : '?'}  chunks ${report.chunks}/${info.chunks}\n` +
      `${(report.bytes / 1048576).toFixed(2)} MiB received\n` +
      `first frame ${report.firstFrameMs === null ? '-' : report.firstFrameMs.toFixed(0) + ' ms'}`;
  }

  async function onChunk(index, ck) {
    const tag = td.decode(ck.subarray(0, 4));
    const p = ck.subarray(12);
    if (chunks[index]) return;
    if (!r && tag !== 'HEAD') { pendingChunks.push([index, ck]); return; }
    chunks[index] = ck;
    report.chunks++;
    if (report.chunks === info.chunks) finish();
    if (tag === 'HEAD') {
      h = JSON.parse(td.decode(p));
      orbit = orbitOf(h);
      view.elevation = orbit.elevation;
      view.baseRadius = orbit.radius;
      const kind = { object: 0, forward: 1, unbounded: 2 }[h.kind];
      const dyn = h.frames && h.frames.length > 1 ? 1 : 0;
      const res = await fetch(`/march.wgsl?kind=${kind}&dynamic=${dyn}&block=${h.block}`);
      if (!res.ok) throw new Error('shader: HTTP ' + res.status);
      r = new Renderer(device, h, await res.text(), wg);
      if (dyn) {
        const tb = $('time');
        tb.min = h.frames[0].time; tb.max = h.frames[h.frames.length - 1].time; tb.value = time;
        $('timebox').hidden = false;
        tb.oninput = () => { time = parseFloat(tb.value); sendPose(); redraw(); };
      }
      for (const q of pendingChunks.splice(0)) await onChunk(q[0], q[1]);
    } else if (tag === 'VMLP') { r.setMlp(p); r.mlp = true; }
    else if (tag === 'GRID') { r.setGrid(u32(p, 0), new Uint32Array(p.slice(4).buffer)); }
    else if (tag === 'BLKS') { const n = u32(p, 4); r.setBlocks(u32(p, 0), n, p.subarray(8)); report.blocks += n; }
    if (r && r.mlp && r.grids.every((g) => g)) {
      // The first frame is drawn as soon as the small parts are in, before more blocks are
      // taken in (chunks are applied one at a time): progressive from the first block on.
      if (report.firstFrameMs === null) { dirty = true; await draw(); } else redraw();
    }
  }
  const pendingChunks = [];

  // Records: u32 chunk index, then the chunk (tag, u32 length, u32 CRC-32, payload).
  let queue = Promise.resolve();
  async function readStream(s) {
    const rd = new Reader(s);
    for (;;) {
      const head = await rd.take(16);
      if (!head) return;
      const index = u32(head, 0), len = u32(head, 8), crc = u32(head, 12);
      if (index >= info.chunks || len > info.size) throw new Error(`bad record for chunk ${index}`);
      const payload = len ? await rd.take(len) : new Uint8Array(0);
      if (!payload && len) throw new Error('stream ended inside a record');
      if (crc32(payload) !== crc) throw new Error(`chunk ${index}: checksum mismatch`);
      const ck = new Uint8Array(12 + len);
      ck.set(head.subarray(4)); ck.set(payload, 12);
      report.bytes += 16 + len;
      queue = queue.then(() => onChunk(index, ck)).catch(abort);
    }
  }
  if (!fixedCam) attachOrbit(view, () => { if (orbit) { sendPose(); redraw(); } });
  $('view').hidden = false;
  setStatus(`streaming ${info.name}: ${info.size} bytes in ${info.chunks} chunks`);

  wt.closed.then(
    (i) => abort(new Error(`the server closed the session (code ${i.closeCode}: ${i.reason})`)),
    (e) => abort(new Error(`the session failed: ${e.message || e}`)),
  );
  (async () => {
    const uni = wt.incomingUnidirectionalStreams.getReader();
    for (;;) {
      const { value, done } = await uni.read();
      if (done) return;
      readStream(value).catch(abort);
    }
  })().catch(abort);
  await complete;
  await queue;
  clearInterval(poseTimer);
  if (report.chunks < info.chunks) throw new Error(`the stream ended with ${report.chunks} of ${info.chunks} chunks`);
  // The file is the preamble then every chunk in order; check it end to end.
  const parts = [unhex(info.preamble), ...chunks];
  const total = parts.reduce((a, b) => a + b.length, 0);
  const file = new Uint8Array(total);
  let o = 0;
  for (const p of parts) { file.set(p, o); o += p.length; }
  report.sha256 = hex(new Uint8Array(await crypto.subtle.digest('SHA-256', file)));
  if (report.sha256 !== info.sha256) throw new Error(`SHA-256 mismatch: got ${report.sha256}, expected ${info.sha256}`);
  wt.close({ closeCode: 0, reason: 'done' });
  redraw();
  // Wait for the complete frame.
  while (!report.lastRender || !report.lastRender.complete || rendering || dirty) await new Promise((res) => setTimeout(res, 10));
  report.state = 'done';
  setStatus(`${info.name}: ${total} bytes, SHA-256 verified; drag to orbit, wheel to zoom`);
}

function attachOrbit(view, changed) {
  const cv = $('canvas');
  let last = null;
  cv.addEventListener('pointerdown', (e) => { last = [e.clientX, e.clientY]; cv.setPointerCapture(e.pointerId); });
  cv.addEventListener('pointerup', () => { last = null; });
  cv.addEventListener('pointermove', (e) => {
    if (!last) return;
    const dx = e.clientX - last[0], dy = e.clientY - last[1];
    last = [e.clientX, e.clientY];
    view.yaw -= dx * 0.01;
    view.pitch = Math.max(-1.5, Math.min(1.5, (view.pitch ?? view.elevation) + dy * 0.01));
    changed();
  });
  cv.addEventListener('wheel', (e) => {
    e.preventDefault();
    view.radius = (view.radius ?? view.baseRadius) * Math.exp(e.deltaY * 0.001);
    changed();
  }, { passive: false });
}

async function main() {
  if (!token) throw new Error('no access token: open the address snerf serve printed (it ends in #token=…)');
  if (typeof WebTransport === 'undefined') throw new Error('this browser has no WebTransport (it needs a secure context: https, or http on localhost)');
  if (!navigator.gpu) throw new Error('this browser has no WebGPU');
  config = await (await fetch('/config.json')).json();
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) throw new Error('no WebGPU adapter');
  report.adapter = adapter.info ? `${adapter.info.vendor} ${adapter.info.architecture}` : 'unknown';
  const device = await adapter.requestDevice({ requiredLimits: { maxTextureDimension3D: adapter.limits.maxTextureDimension3D } });
  device.addEventListener('uncapturederror', (e) => fail('WebGPU: ' + e.error.message));
  const assets = await listAssets();
  report.listing = assets;
  const tbody = $('assets').querySelector('tbody');
  for (const a of assets) {
    const tr = document.createElement('tr');
    for (const v of [a.name, `${(a.size / 1048576).toFixed(2)} MiB`, a.kind || '?']) {
      const td_ = document.createElement('td'); td_.textContent = v; tr.appendChild(td_);
    }
    const b = document.createElement('button');
    b.textContent = 'view';
    b.onclick = () => { location.hash = new URLSearchParams({ ...Object.fromEntries(frag), asset: a.name }).toString(); location.reload(); };
    const td2 = document.createElement('td'); td2.appendChild(b); tr.appendChild(td2);
    tbody.appendChild(tr);
  }
  report.state = 'listed';
  setStatus(`${assets.length} asset(s); choose one`);
  const want = frag.get('asset');
  if (want) await stream(want, device, config.workgroup);
}

main().catch(fail);
