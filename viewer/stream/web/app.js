// snerf web viewer: lists the served assets, streams one over WebTransport (`snerf/1`, see
// viewer/stream/PROTOCOL.md) and ray-marches it with WebGPU. The march is the compute shader
// of shaders/march.wgsl, composed by the server exactly as the native viewer composes it
// (GET /march.wgsl); this file only does what the native viewer's host code does: parse the
// chunks, place blocks in the atlas texture, pack the grid, lay out the MLP and the params.
// Without WebGPU (older headset browsers) it draws with WebGL2: the same march, the fragment
// target of shaders/march.wgsl translated to GLSL ES 3.00 by the server (GET /march.glsl).
//
// URL fragment (never sent to the server): token=HEX (required), asset=NAME (stream it right
// away), cam=JSON ({c2w:[[4],[4],[4]], fx, fy, cx, cy, width, height}: a fixed camera),
// time=T (playback time of a 4D asset). URL query manifest=URL: a scene written by `snerf
// publish` on any static host (no token; see ManifestSession).

// xr.js (immersive mode) is imported when the stream starts, not before this script runs:
// the first frame does not wait for its download.

const EMPTY = 0xffffffff;
const $ = (id) => document.getElementById(id);
const frag = new URLSearchParams(location.hash.slice(1));
const token = frag.get('token') || '';
const fixedCam = frag.get('cam') ? JSON.parse(frag.get('cam')) : null;

// What the page reports (read by tests and the stats overlay).
const report = (window.snerf = {
  state: 'starting', error: null, listing: null, asset: null, sha256: null, bytes: 0,
  chunks: 0, blocks: 0, firstFrameMs: null, frames: 0, frame: null, firstFrame: null,
  adapter: null, backend: null, marks: {}, crcMs: 0, rotationRetries: 0, transport: null,
});
// Marks (performance.now(), ms since navigation) of the steps to the first frame: script,
// config, adapter, device, present (the present pipeline compiled), connected, welcome,
// header, shader (its text fetched), pipeline (compiled), ready (pipeline, MLP and grids
// in), submitted (the first march), firstFrame (its GPU work done), listing (asked for).
report.marks.script = performance.now();

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
// CRC-32 (IEEE), slicing by 4: four table lookups per 4 bytes instead of one per byte.
const CRC = (() => {
  const t = new Uint32Array(1024);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    t[n] = c >>> 0;
  }
  for (let n = 0; n < 256; n++) for (let k = 1; k < 4; k++) t[256 * k + n] = (t[256 * (k - 1) + n] >>> 8) ^ t[t[256 * (k - 1) + n] & 255];
  return t;
})();
function crc32(b) {
  let c = 0xffffffff, i = 0;
  const n = b.length;
  for (; i + 4 <= n; i += 4) {
    c ^= b[i] | (b[i + 1] << 8) | (b[i + 2] << 16) | (b[i + 3] << 24);
    c = CRC[768 + (c & 255)] ^ CRC[512 + ((c >>> 8) & 255)] ^ CRC[256 + ((c >>> 16) & 255)] ^ CRC[c >>> 24];
  }
  for (; i < n; i++) c = CRC[(c ^ b[i]) & 255] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}
function frame(msg) {
  const j = te.encode(JSON.stringify(msg));
  const out = new Uint8Array(4 + j.length);
  new DataView(out.buffer).setUint32(0, j.length, true);
  out.set(j, 4);
  return out;
}

// Reads exact byte counts from a WebTransport stream. The pieces the stream delivers are kept
// as they are and copied once into each record (appending them to one buffer would copy a
// large record once per piece).
class Reader {
  constructor(readable) { this.r = readable.getReader(); this.parts = []; this.len = 0; this.done = false; }
  async fill(n) {
    while (this.len < n && !this.done) {
      const { value, done } = await this.r.read();
      if (done) { this.done = true; break; }
      if (value.length) { this.parts.push(value); this.len += value.length; }
    }
    return this.len >= n;
  }
  // n bytes, or null at a clean end of stream before any of them.
  async take(n) {
    if (!(await this.fill(n))) {
      if (this.len === 0) return null;
      throw new Error('stream ended inside a record');
    }
    let out;
    const p0 = this.parts[0];
    if (p0.length >= n) {
      out = p0.subarray(0, n);
      if (p0.length === n) this.parts.shift(); else this.parts[0] = p0.subarray(n);
    } else {
      out = new Uint8Array(n);
      let o = 0;
      while (o < n) {
        const p = this.parts[0], k = Math.min(p.length, n - o);
        out.set(p.subarray(0, k), o);
        o += k;
        if (k === p.length) this.parts.shift(); else this.parts[0] = p.subarray(k);
      }
    }
    this.len -= n;
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

// ---- snerf/1 over HTTPS (browsers without WebTransport) ----
// PROTOCOL.md, "Over HTTPS": each request carries the client's control frames (the hello says
// what is held and where the head looks); the answers are the server's control frames or the
// next batch of records. This class offers the part of a WebTransport session the page uses
// (a bidirectional control stream, incoming data streams, pose datagrams, closed/close), so
// everything above it is one code path for both carriers.
class HttpSession {
  constructor(url) {
    this.url = url;
    this.hello = null; this.info = null; this.held = null; this.pose = null; this.stopped = false;
    this.ready = Promise.resolve();
    this.closed = new Promise((res, rej) => { this.closeWith = res; this.fail = rej; });
    this.closed.catch(() => {});
    this.incomingUnidirectionalStreams = new ReadableStream({ start: (c) => { this.uni = c; } });
    this.ctlReadable = new ReadableStream({ start: (c) => { this.ctl = c; } });
    // A pose "datagram" waits for the next request's hello.
    this.datagrams = { writable: new WritableStream({ write: (b) => { this.pose = decodePose(b); } }) };
  }
  async post(part, msgs) {
    const fr = msgs.map(frame), body = new Uint8Array(fr.reduce((n, f) => n + f.length, 0));
    fr.reduce((o, f) => (body.set(f, o), o + f.length), 0);
    const r = await fetch(`${this.url}?part=${part}`, { method: 'POST', body, cache: 'no-store' });
    if (!r.ok) {
      // A refusal: the snerf/1 close code is the body's first word, as a session would close.
      const t = await r.text();
      const e = { closeCode: parseInt(t, 10), reason: t.slice(t.indexOf(' ') + 1) };
      this.stop(e);
      throw new Error(`the server refused (code ${e.closeCode}: ${e.reason})`);
    }
    return r;
  }
  stop(info) {
    if (this.stopped) return;
    this.stopped = true;
    try { this.ctl.close(); this.uni.close(); } catch { /* already closed */ }
    this.closeWith(info);
  }
  close(info) { this.stop(info || { closeCode: 0, reason: 'done' }); }
  async createBidirectionalStream() {
    const writable = new WritableStream({
      write: async (chunk) => {
        const msg = JSON.parse(td.decode(chunk.subarray(4)));
        if (msg.type === 'hello') this.hello = msg;
        const r = await this.post('control', msg.type === 'hello' ? [msg] : [this.hello, msg]);
        const b = new Uint8Array(await r.arrayBuffer());
        for (let o = 0; o < b.length; ) {
          const f = b.subarray(o, o + 4 + u32(b, o));
          o += f.length;
          const m = JSON.parse(td.decode(f.subarray(4)));
          // The hello goes again with every request: its welcome is passed on once.
          if (m.type === 'welcome' && msg.type !== 'hello') continue;
          this.ctl.enqueue(f);
          if (m.type === 'welcome' && m.asset) this.start(m);
        }
      },
    });
    return { writable, readable: this.ctlReadable };
  }
  start(welcome) {
    this.info = welcome.asset;
    this.held = new Uint8Array(this.info.chunks);
    if (welcome.resumed) for (const [a, b] of this.hello.have || []) this.held.fill(1, a, Math.min(b, this.info.chunks));
    this.pump().catch((e) => { if (!this.stopped) { this.stopped = true; this.fail(e); } });
  }
  // One request at a time: the next is asked for when the last answer has been read, with
  // what is held now and the latest pose.
  async pump() {
    while (!this.stopped) {
      const have = [];
      this.held.forEach((h, i) => { if (!h) return; if (have.length && have[have.length - 1][1] === i) have[have.length - 1][1] = i + 1; else have.push([i, i + 1]); });
      const hello = { ...this.hello, have, resume_id: this.info.sha256 };
      if (this.pose) hello.pose = this.pose;
      const r = await this.post('data', [hello]);
      let done;
      const finished = new Promise((res) => { done = res; });
      const track = recordTracker((i) => { this.held[i] = 1; });
      let bytes = 0;
      const counted = new TransformStream({ transform: (c, ctl) => { bytes += c.length; track(c); ctl.enqueue(c); }, flush: () => done() });
      this.uni.enqueue(r.body.pipeThrough(counted));
      await finished;
      if (bytes === 0) return; // the server has nothing more: the page closes when it has all
    }
  }
}

// ---- a published scene (snerf publish; viewer/stream/PUBLISH.md) ----
// Opened as index.html?manifest=URL (relative to the page, or on another origin with CORS):
// no snerf process in the path. The manifest lists content-addressed objects (name = SHA-256)
// and where every file chunk lives in them; this class fetches the objects, most urgent for
// the latest pose first (the server's planner, below), checks each object's SHA-256 (once
// more past the caches if wrong, then the session fails: no byte of a bad object is drawn),
// and hands the chunks to the page as records on "streams", as a WebTransport session would.
const manifestUrl = new URLSearchParams(location.search).get('manifest');
let published = null; // { m, url }: the manifest and its URL, once read
async function readManifest() {
  if (published) return published;
  const url = new URL(manifestUrl, location.href);
  const r = await fetch(url, { cache: 'no-cache' });
  if (!r.ok) throw new Error(`${url}: HTTP ${r.status}`);
  const m = await r.json();
  if (m.format !== 'snerf-publish') throw new Error(`${url}: not a snerf manifest`);
  if (m.version !== 1) throw new Error(`${url}: manifest format version ${m.version}; this page reads version 1`);
  published = { m, url, base: new URL(m.objects_base, url) };
  return published;
}
// An object's bytes, checked against its name; once more under a query of its own (no cache
// holds it, so the origin answers) if wrong.
async function fetchObject(base, sha, size) {
  let why = '';
  for (let attempt = 0; attempt < 2; attempt++) {
    const u = new URL(sha + (attempt ? `?refetch=${Date.now().toString(16)}${Math.random().toString(16).slice(2)}` : ''), base);
    try {
      const r = await fetch(u);
      if (!r.ok) { why = `HTTP ${r.status}`; continue; }
      const b = new Uint8Array(await r.arrayBuffer());
      if (size !== undefined && b.length !== size) { why = `${b.length} bytes, the manifest says ${size}`; continue; }
      const got = hex(new Uint8Array(await crypto.subtle.digest('SHA-256', b)));
      if (got !== sha) { why = `SHA-256 mismatch (got ${got})`; continue; }
      // Which HTTP carried it (h3, h2, http/1.1), for the tests and benchmarks.
      const e = performance.getEntriesByName(u.href)[0];
      if (e && e.nextHopProtocol) (report.httpProtocols ||= {})[e.nextHopProtocol] = ((report.httpProtocols || {})[e.nextHopProtocol] || 0) + 1;
      return b;
    } catch (e) { why = String(e.message || e); }
  }
  throw new Error(`object ${sha}: ${why}, twice`);
}
// The shaders a published scene carries (objects too), checked like the rest.
async function publishedFile(name) {
  const { m, base } = await readManifest();
  const sha = { 'present.wgsl': m.web.present_wgsl, 'march.wgsl': m.web.march_wgsl, 'march.glsl': m.web.march_glsl }[name];
  return new Response(await fetchObject(base, sha));
}

// The server's block planner (viewer/stream/src/plan.rs: `ServedAsset::priority`,
// `View::new`, `order_blocks`), in f32 like the Rust (Math.fround after every operation), so
// it gives the same order for the same pose. tests/publish.rs compares the two on a pose.
const f32 = Math.fround;
const fsub = (a, b) => [f32(a[0] - b[0]), f32(a[1] - b[1]), f32(a[2] - b[2])];
const fdot = (a, b) => f32(f32(f32(a[0] * b[0]) + f32(a[1] * b[1])) + f32(a[2] * b[2]));
const fnorm = (a) => f32(Math.sqrt(fdot(a, a)));
const PI_F32 = f32(Math.PI);
function planView(m, pose) {
  if (!pose) return null;
  const fw = pose.forward.map(f32), n = Math.max(fnorm(fw), f32(1e-12));
  const fov = f32(pose.fov_deg) > 0 ? f32(pose.fov_deg) : 90;
  const frames = m.header.frames || null;
  let frame = 0;
  if (frames) { for (let i = frames.length - 1; i >= 0; i--) if (f32(frames[i].time) <= f32(pose.time)) { frame = i; break; } }
  return { eye: pose.eye.map(f32), forward: fw.map((x) => f32(x / n)), half: f32(f32(fov * 0.5) * f32(PI_F32 / 180)), frame };
}
function planKey(m, b, v) {
  const nf = m.asset.frames, k = v ? v.frame : 0;
  let rank = nf;
  for (const [lo, hi] of b.frames) rank = Math.min(rank, lo <= k && k <= hi ? 0 : lo > k ? lo - k : lo + nf - k);
  if (!v) return [rank, 0, fnorm(fsub(b.centre, m.origin))];
  const d = fsub(b.centre, v.eye), len = fnorm(d), r = f32(b.radius);
  const near = Math.max(f32(len - r), 0);
  if (len <= r || len < f32(1e-9)) return [rank, 0, 0];
  const cos = f32(fdot(d, v.forward) / len);
  const ang = f32(f32(Math.acos(Math.min(1, Math.max(-1, cos)))) - f32(Math.asin(Math.min(f32(r / len), 1))));
  return [rank, ang <= v.half ? 0 : cos > 0 ? 1 : 2, near];
}
// Block indices (into m.blocks), most urgent first.
function orderBlocks(m, pose) {
  const v = planView(m, pose);
  const keyed = m.blocks.map((b, i) => [planKey(m, b, v), i]);
  // order_blocks sorts most urgent last (stable, descending) and sends from the end.
  keyed.sort((a, b) => b[0][0] - a[0][0] || b[0][1] - a[0][1] || b[0][2] - a[0][2]);
  return keyed.map((k) => k[1]).reverse();
}
// Objects, most urgent first: those of HEAD, VMLP, GRIDs and END, then by their most urgent
// block (publish.rs, `Manifest::object_order`). `skip[o]`: leave object o out.
function orderObjects(m, pose, skip) {
  const seen = new Uint8Array(m.objects.length), out = [];
  if (skip) skip.forEach((s, i) => { if (s) seen[i] = 1; });
  const take = (o) => { if (!seen[o]) { seen[o] = 1; out.push(o); } };
  for (const c of [...m.meta, m.end]) take(m.chunks[c][0]);
  for (const b of orderBlocks(m, pose)) take(m.chunks[m.blocks[b].chunk][0]);
  return out;
}

class ManifestSession {
  constructor() {
    this.hello = null; this.pose = null; this.stopped = false; this.parallel = 4;
    this.ready = readManifest().then(() => {});
    this.closed = new Promise((res, rej) => { this.closeWith = res; this.fail = rej; });
    this.closed.catch(() => {});
    this.incomingUnidirectionalStreams = new ReadableStream({ start: (c) => { this.uni = c; } });
    this.ctlReadable = new ReadableStream({ start: (c) => { this.ctl = c; } });
    this.datagrams = { writable: new WritableStream({ write: (b) => { this.pose = decodePose(b); } }) };
  }
  stop(info) {
    if (this.stopped) return;
    this.stopped = true;
    try { this.ctl.close(); this.uni.close(); } catch { /* already closed */ }
    this.closeWith(info);
  }
  close(info) { this.stop(info || { closeCode: 0, reason: 'done' }); }
  async createBidirectionalStream() {
    const { m } = await readManifest();
    const writable = new WritableStream({
      write: (chunk) => {
        const msg = JSON.parse(td.decode(chunk.subarray(4)));
        if (msg.type === 'hello') {
          this.hello = msg;
          if (msg.pose) this.pose = msg.pose;
          const held = new Uint8Array(m.asset.chunks);
          for (const [a, b] of msg.have || []) held.fill(1, a, Math.min(b, held.length));
          this.ctl.enqueue(frame({ type: 'welcome', version: 1, asset: msg.asset === null ? null : m.asset, resumed: (msg.have || []).length > 0, sending_chunks: held.length - held.reduce((n, h) => n + h, 0), sending_bytes: 0 }));
          if (msg.asset !== null) this.start(m, held);
        } else if (msg.type === 'list') {
          const kinds = { object: 'object', forward: 'forward', unbounded: 'unbounded' };
          this.ctl.enqueue(frame({ type: 'listing', assets: [{ name: m.asset.name, size: m.asset.size, kind: kinds[m.header.kind] || null }] }));
        }
      },
    });
    return { writable, readable: this.ctlReadable };
  }
  start(m, held) {
    // Which chunks each object holds; objects whose chunks are all held are not fetched.
    this.objChunks = m.objects.map(() => []);
    m.chunks.forEach((c, i) => this.objChunks[c[0]].push(i));
    const skip = this.objChunks.map((cs) => cs.every((i) => held[i]));
    this.requested = Uint8Array.from(skip, (s) => (s ? 1 : 0));
    report.planPose = this.pose ? { ...this.pose, fov_deg: f32(this.pose.fov_deg) } : null;
    report.planBlocks = orderBlocks(m, this.pose);
    report.planObjects = orderObjects(m, this.pose, null);
    report.objectsFetched = [];
    const worker = async () => {
      for (;;) {
        if (this.stopped) return;
        // The most urgent object not yet asked for, for the pose now.
        const o = orderObjects(m, this.pose, this.requested)[0];
        if (o === undefined) return;
        this.requested[o] = 1;
        const obj = await fetchObject(published.base, m.objects[o].sha256, m.objects[o].size);
        report.objectsFetched.push(o);
        const recs = this.objChunks[o].filter((i) => !held[i]).map((i) => {
          const c = m.chunks[i], r = new Uint8Array(4 + c[2]);
          new DataView(r.buffer).setUint32(0, i, true);
          r.set(obj.subarray(c[1], c[1] + c[2]), 4);
          return r;
        });
        if (this.stopped) return;
        this.uni.enqueue(new ReadableStream({ start: (c) => { for (const r of recs) c.enqueue(r); c.close(); } }));
      }
    };
    // An object wrong twice (asked again past the caches) is final: the session ends as one
    // whose client rejected data (code 11), which the page does not resume.
    Promise.all(Array.from({ length: this.parallel }, worker)).catch((e) => this.stop({ closeCode: 11, reason: String(e.message || e) }));
  }
}

// Calls `onRecord(index)` for each whole record (u32 index + chunk: tag, u32 length, CRC,
// payload) in the bytes it is fed, piece by piece.
function recordTracker(onRecord) {
  let head = new Uint8Array(16), have = 0, skip = 0;
  return (c) => {
    let o = 0;
    while (o < c.length) {
      if (skip > 0) { const k = Math.min(skip, c.length - o); skip -= k; o += k; if (skip === 0) onRecord(u32(head, 0)); continue; }
      const k = Math.min(16 - have, c.length - o);
      head.set(c.subarray(o, o + k), have); have += k; o += k;
      if (have === 16) { have = 0; skip = u32(head, 8); if (skip === 0) onRecord(u32(head, 0)); }
    }
  };
}

// The 40-byte pose datagram back into the hello's pose.
function decodePose(b) {
  const dv = new DataView(b.buffer, b.byteOffset, b.byteLength), f = (i) => dv.getFloat32(8 + 4 * i, true);
  return { eye: [f(0), f(1), f(2)], forward: [f(3), f(4), f(5)], time: f(6), fov_deg: f(7) };
}

// ---- WebTransport ----
// A published scene has no server to ask: its manifest gives the march's workgroup.
const fetchConfig = async () => {
  if (!manifestUrl) return (await fetch('/config.json')).json();
  const { m } = await readManifest();
  return { protocol: 1, webtransport: null, cert_hash: null, workgroup: m.web.workgroup };
};
// True while an immersive WebXR session draws (its frame loop replaces the page's).
let xrActive = false;
// How often a handshake is tried again after the certificate was rotated under it.
const ROTATION_RETRIES = 3;
async function connect(hello, firstConfig = null) {
  let wt;
  for (let attempt = 0; ; attempt++) {
    // The server rotates its generated certificate: take the hash in use now (on the first
    // try, `firstConfig` when given: the page's own read of it as it started, moments ago).
    // (Each call its own: the stream's and the listing's sessions may be opened together.)
    const config = attempt === 0 && firstConfig ? await firstConfig : await fetchConfig();
    const opts = {};
    if (config.cert_hash) opts.serverCertificateHashes = [{ algorithm: 'sha-256', value: unhex(config.cert_hash) }];
    // WebTransport where the browser has it; else snerf/1 over HTTPS requests; a published
    // scene's objects over whatever HTTP the host speaks (HTTP/3, HTTP/2).
    if (manifestUrl) { wt = new ManifestSession(); report.transport = 'manifest'; }
    else {
      wt = typeof WebTransport === 'undefined' ? new HttpSession('/snerf/1/http') : new WebTransport(config.webtransport, opts);
      report.transport = typeof WebTransport === 'undefined' ? 'https' : 'webtransport';
    }
    wt.closed.catch(() => {}); // a failed handshake rejects this too; `ready` reports it
    try {
      await wt.ready;
      break;
    } catch (e) {
      // A rotation between reading the hash and the handshake fails the handshake with a hash
      // that is no longer the server's: read the new one and try again. Any other failure
      // (the server down, a hash that has not changed) is the caller's to handle.
      if (!config.cert_hash || attempt >= ROTATION_RETRIES) throw e;
      const now = await fetchConfig();
      if (now.cert_hash === config.cert_hash) throw e;
      report.rotationRetries += 1;
    }
  }
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
  await writer.write(frame({ type: 'list', thumbs: true }));
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

// ---- the renderers (host side of viewer/src/gpu.rs) ----
// A style switch (PROTOCOL.md, "Style switches"): another style's colour part written over
// the style held, chunk by chunk as it streams; the density stays. snerf_asset::Recolour in
// JavaScript (FORMAT.md, multi-style assets): a block's SCOL holds the colour of its *stored*
// voxels, those that are live (some voxel of their 3x3x3 neighbourhood has density; in a 4D
// asset lerped between keyframes, every voxel) and not held by another voxel (an apron voxel
// of a static asset whose blocks each serve one cell is copied from the block of the cell it
// lies in; of a 4D asset blended by density, from the nearest interior voxel of its block). `chunks`: the held file's chunks by
// index (BLKS chunks are rewritten in place); `blkChunk[b]`: the chunk holding block b.
class Recolour {
  constructor(h, grid, chunks, blkChunk, voxelBytes) {
    const b = h.block, e = b + 2, g = h.res / b, nb = h.atlas_blocks, nv = e * e * e, n = voxelBytes;
    Object.assign(this, { h, chunks, blkChunk, n, nv, nb, have: new Uint8Array(nb) });
    const data = (k) => chunks[blkChunk[k]].subarray(20);
    // a static asset's blocks serving exactly one cell: their cell
    const cellOf = new Int32Array(nb).fill(-1);
    if (!h.frames) {
      const uses = new Uint32Array(nb);
      for (let c = 0; c < grid.length; c++) if (grid[c] !== EMPTY) { uses[grid[c]]++; cellOf[grid[c]] = c; }
      for (let k = 0; k < nb; k++) if (uses[k] !== 1) cellOf[k] = -1;
    }
    // Per axis, a block-local index l of cell coordinate c: [holder's cell coordinate, its
    // local index], or null off the grid.
    const axis = (c, l) => {
      const gi = c * b + l - 1;
      if (gi < 0 || gi >= g * b) return null;
      const oc = Math.floor(gi / b);
      return [oc, gi - oc * b + 1];
    };
    // apron voxel (x, y, z) of the block of cell c: [holder block, its voxel], or null
    const owner = (c, x, y, z) => {
      const ax = axis(c % g, x), ay = axis(Math.floor(c / g) % g, y), az = axis(Math.floor(c / (g * g)), z);
      if (!ax || !ay || !az) return null;
      const o = grid[(az[0] * g + ay[0]) * g + ax[0]];
      if (o === EMPTY || cellOf[o] < 0) return null;
      return [o, (az[1] * e + ay[1]) * e + ax[1]];
    };
    this.stored = []; this.crc = new Uint32Array(nb); this.from = []; this.to = Array.from({ length: nb }, () => []);
    for (let k = 0; k < nb; k++) {
      const d = data(k), dens = new Uint8Array(nv);
      for (let v = 0; v < nv; v++) dens[v] = d[v * n];
      this.crc[k] = crc32(dens);
      let live = new Uint8Array(nv);
      if (h.frames && !h.colour_by_density) live.fill(1);
      else {
        for (let v = 0; v < nv; v++) live[v] = dens[v] > 0 ? 1 : 0;
        for (const stride of [1, e, e * e]) {
          const src = live.slice();
          for (let i = 0; i < nv; i++) {
            const q = Math.floor(i / stride) % e;
            live[i] = src[i] || (q > 0 && src[i - stride]) || (q + 1 < e && src[i + stride]) ? 1 : 0;
          }
        }
      }
      const from = [];
      if (h.frames && h.colour_by_density) {
        // a 4D block blended by density: every apron voxel is held by the nearest interior
        // voxel of its own block
        const cl = (q) => Math.min(Math.max(q, 1), b);
        for (let z = 0, v = 0; z < e; z++) for (let y = 0; y < e; y++) for (let x = 0; x < e; x++, v++) {
          if (x >= 1 && x <= b && y >= 1 && y <= b && z >= 1 && z <= b) continue;
          const ov = (cl(z) * e + cl(y)) * e + cl(x);
          from.push(v, k, ov); live[v] = 0;
        }
      } else if (cellOf[k] >= 0) {
        for (let z = 0, v = 0; z < e; z++) for (let y = 0; y < e; y++) for (let x = 0; x < e; x++, v++) {
          if (x >= 1 && x <= b && y >= 1 && y <= b && z >= 1 && z <= b) continue; // interior: its own
          const o = owner(cellOf[k], x, y, z);
          if (o) { from.push(v, o[0], o[1]); this.to[o[0]].push(k, v, o[1]); live[v] = 0; }
        }
      }
      this.stored.push(live);
      this.from.push(from);
    }
  }
  // One SCOL payload (style, block, density checksum, colours) written; returns the blocks
  // whose bytes changed (its own and the neighbours whose aprons it holds).
  apply(p) {
    const k = u32(p, 4), n = this.n, cc = n - 1;
    if (k >= this.nb) throw new Error(`colour for block ${k} of ${this.nb}`);
    if (u32(p, 8) !== this.crc[k]) throw new Error(`the colour of block ${k} was made for another geometry`);
    const st = this.stored[k];
    let count = 0;
    for (let v = 0; v < this.nv; v++) count += st[v];
    if (p.length - 12 !== count * cc) throw new Error(`the colour of block ${k} has ${p.length - 12} bytes, the block stores ${count} voxels`);
    const data = (j) => this.chunks[this.blkChunk[j]].subarray(20);
    const d = data(k);
    let o = 12;
    for (let v = 0; v < this.nv; v++) {
      if (st[v]) { d.set(p.subarray(o, o + cc), v * n + 1); o += cc; } else d.fill(0, v * n + 1, v * n + n);
    }
    this.have[k] = 1;
    const f = this.from[k];
    for (let i = 0; i < f.length; i += 3) d.set(data(f[i + 1]).subarray(f[i + 2] * n + 1, f[i + 2] * n + n), f[i] * n + 1);
    const t = this.to[k], changed = [k];
    for (let i = 0; i < t.length; i += 3) {
      data(t[i]).set(d.subarray(t[i + 2] * n + 1, t[i + 2] * n + n), t[i + 1] * n + 1);
      if (changed[changed.length - 1] !== t[i]) changed.push(t[i]);
    }
    return [...new Set(changed)];
  }
}

// What both renderers (WebGPU, WebGL2) share: the atlas layout, the packed grid, the MLP's
// layout, the silhouette pass's choice and the params struct (one layout: the WGSL `Params`,
// a uniform buffer on WebGPU, a std140 uniform block on WebGL2).
class MarchHost {
  constructor(h, maxDim3D) {
    this.slots = [];
    this.h = h;
    this.g = h.res / h.block;
    this.g3 = this.g ** 3;
    this.frames = h.frames ? h.frames.length : 1;
    this.edge = h.block + 2;
    this.layout = planAtlas(h.atlas_blocks, this.edge, maxDim3D);
    // a diffuse asset's voxel is density and RGB alone (its features are zero): one u32
    this.voxelBytes = h.diffuse ? 4 : 8;
    this.grids = new Array(this.frames).fill(null);
    this.present = new Uint8Array(h.atlas_blocks);
    this.gridDirty = true;
  }
  texels() { const l = this.layout; return [l.nx * l.edge, l.ny * l.edge, l.nz * l.edge]; }
  packed(b) { const l = this.layout; return (b % l.nx) | ((Math.floor(b / l.nx) % l.ny) << 10) | (Math.floor(b / (l.nx * l.ny)) << 20); }
  origin(b) { const l = this.layout; return [(b % l.nx) * l.edge, (Math.floor(b / l.nx) % l.ny) * l.edge, Math.floor(b / (l.nx * l.ny)) * l.edge]; }
  // The view MLP transposed to input-major vec4 rows (gpu.rs `mlp_gpu_layout`): 225 vec4.
  mlpRows(payload) {
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
    return v;
  }
  setGrid(frameIndex, entries) { this.grids[frameIndex] = entries; this.gridDirty = true; }
  // Every keyframe's grid, entries packed, those of blocks not yet uploaded EMPTY.
  gridEntries() {
    const host = new Uint32Array(this.g3 * this.frames).fill(EMPTY);
    for (let f = 0; f < this.frames; f++) {
      const g = this.grids[f];
      if (!g) continue;
      for (let i = 0; i < this.g3; i++) {
        const e = g[i];
        // motion entries (bit 31 set, bit 30 clear; FORMAT.md "Motion") pass as they are
        if ((e & 0xc0000000) >>> 0 === 0x80000000) host[f * this.g3 + i] = e;
        else if (e !== EMPTY && this.present[e]) host[f * this.g3 + i] = this.packed(e);
      }
    }
    return host;
  }
  // Side of the sub-pixel grid a silhouette pixel of `cam` takes (1: none): the header's
  // pixel_rays (absent: 1), as the field was trained, for cameras whose pixels are at least
  // 1/√2 as coarse as the training views' (train_pixel; absent: every camera). Header::pixel_rays_for
  // and snerf_geometry::silhouette::draws_pixel_means, in JavaScript.
  pixelSide(cam) {
    const h = this.h, c = h.space.center, e = [cam.c2w[0][3], cam.c2w[1][3], cam.c2w[2][3]];
    // at the display's own pixels (lodFx: the focal length before the adaptive render scale),
    // so lowering the scale to hold the frame rate never turns the costlier pass on
    const footprint = Math.fround(Math.hypot(e[0] - c[0], e[1] - c[1], e[2] - c[2]) / Math.abs(cam.lodFx || cam.fx));
    const t = h.train_pixel;
    const coarse = !(t > 0 && Number.isFinite(t)) || !(footprint < Math.fround(Math.fround(Math.SQRT1_2) * t));
    return (h.pixel_rays || 1) > 1 && coarse ? Math.round(Math.sqrt(h.pixel_rays)) : 1;
  }
  params(cam, time, side) {
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
    f.set([h.density.logit_min, h.density.logit_max, w], 44);
    u[47] = (h.motion_ref || 0) * this.g3; // the motion reference's grid offset, as bits
    f.set([h.background[0], h.background[1], h.background[2], h.colour_by_density ? 1 : 0], 48); // w: keyframes blend colour by density
    u.set([h.res, this.g, this.layout.nx, this.layout.ny], 52);
    u.set([k0 * this.g3, k1 * this.g3, k0 === k1 ? 1 : 0, side], 56);
    f.set([1 / t[0], 1 / t[1], 1 / t[2], 0], 60);
    return b;
  }
}

// WebGPU: the compute shader of /march.wgsl.
class Renderer extends MarchHost {
  // `present`: {wgsl: shaders/present.wgsl, format, pipeline: a promise of its pipeline for
  // the canvas's `format`, compiled while the page started}.
  constructor(device, h, shader, present, wg) {
    super(h, device.limits.maxTextureDimension3D);
    this.device = device;
    this.presentWgsl = present.wgsl;
    this.wg = wg;
    const t = this.texels();
    this.atlas = device.createTexture({ size: t, dimension: '3d', format: h.diffuse ? 'r32uint' : 'rg32uint', usage: GPUTextureUsage.TEXTURE_BINDING | GPUTextureUsage.COPY_DST });
    // The atlas is zeroed on its first use; a one-texel write (of the zero it holds) has that
    // done now, beside the compile below, rather than in the first frame's submission.
    device.queue.writeTexture({ texture: this.atlas }, new Uint8Array(this.voxelBytes), { bytesPerRow: this.voxelBytes }, [1, 1, 1]);
    this.gridBuf = device.createBuffer({ size: Math.max(4, this.g3 * this.frames * 4), usage: GPUBufferUsage.STORAGE | GPUBufferUsage.COPY_DST });
    this.mlpBuf = device.createBuffer({ size: 900 * 4, usage: GPUBufferUsage.UNIFORM | GPUBufferUsage.COPY_DST });
    // Compiled off the page's thread while the MLP and the grids arrive and the blocks are
    // taken in (SwiftShader takes a good part of a second for the march); `pipeline` is null
    // until then (`ready()` waits for it) and `compiled` resolves with it or rejects.
    this.pipeline = null;
    this.compiled = Promise.all([
      device.createComputePipelineAsync({ layout: 'auto', compute: { module: device.createShaderModule({ code: shader }), entryPoint: 'main' } }),
      present.pipeline,
    ]).then(([p, pp]) => {
      this.pipeline = p;
      if (!this.presentPipe) { this.presentPipe = pp; this.presentFormat = present.format; }
    });
  }
  setMlp(payload) { this.device.queue.writeBuffer(this.mlpBuf, 0, this.mlpRows(payload)); }
  // `data`: `count` blocks of (block+2)^3 voxels, one texel each: 8 bytes (rg32uint), or 4
  // (r32uint) in a diffuse asset, whose file stores density and RGB alone.
  setBlocks(first, count, data) {
    const e = this.edge, n = this.voxelBytes, bb = e * e * e * n;
    for (let k = 0; k < count; k++) {
      const b = first + k;
      this.device.queue.writeTexture({ texture: this.atlas, origin: this.origin(b) }, data.subarray(k * bb, (k + 1) * bb), { bytesPerRow: e * n, rowsPerImage: e }, [e, e, e]);
      this.present[b] = 1;
    }
    this.gridDirty = true;
  }
  uploadGrid() {
    this.device.queue.writeBuffer(this.gridBuf, 0, this.gridEntries());
    this.gridDirty = false;
  }
  // Buffers of one view (slot 0: the page's canvas; slots 0 and 1: the two eyes in XR).
  slot(i, w, hgt) {
    const s0 = this.slots[i];
    if (s0 && s0.w === w && s0.h === hgt) return s0;
    const d = this.device, px = w * hgt, U = GPUBufferUsage;
    const rgba = d.createBuffer({ size: px * 16, usage: U.STORAGE | U.COPY_SRC });
    const depth = d.createBuffer({ size: px * 4, usage: U.STORAGE });
    const cover = d.createBuffer({ size: px * 4, usage: U.STORAGE });
    // one params buffer and bind group per pass: the centre pass, the silhouette pass
    const params = [0, 1].map(() => d.createBuffer({ size: 256, usage: U.UNIFORM | U.COPY_DST }));
    const bind = params.map((p) => d.createBindGroup({
      layout: this.pipeline.getBindGroupLayout(0),
      entries: [
        { binding: 0, resource: { buffer: p } },
        { binding: 1, resource: { buffer: this.gridBuf } },
        { binding: 2, resource: { buffer: this.mlpBuf } },
        { binding: 3, resource: { buffer: rgba } },
        { binding: 4, resource: { buffer: depth } },
        { binding: 5, resource: this.atlas.createView() },
        { binding: 8, resource: { buffer: cover } },
      ],
    }));
    const screen = d.createBuffer({ size: 16, usage: U.UNIFORM | U.COPY_DST });
    const s = { w, h: hgt, rgba, depth, cover, params, bind, screen, present: null, readback: null };
    if (s0) for (const b of [s0.rgba, s0.depth, s0.cover, ...s0.params, s0.screen, s0.readback]) if (b) b.destroy();
    return (this.slots[i] = s);
  }
  // March `views` ([{cam, x, y}]) at `time` in one submission; present each into `target`
  // (a GPUTexture, or null) at viewport origin (x, y) with shaders/present.wgsl, as the native
  // window does; with `capture`, read every view back (Float32Array of width*height RGBA,
  // A = opacity) — what the tests compare with the CPU reference.
  async render(views, time, target, capture) {
    const d = this.device;
    if (this.gridDirty) this.uploadGrid();
    const slots = views.map((v, i) => this.slot(i, v.cam.width, v.cam.height));
    const sides = views.map((v) => this.pixelSide(v.cam));
    this.lastSides = sides;
    views.forEach((v, i) => {
      d.queue.writeBuffer(slots[i].params[0], 0, this.params(v.cam, time, 0));
      d.queue.writeBuffer(slots[i].params[1], 0, this.params(v.cam, time, sides[i]));
    });
    const enc = d.createCommandEncoder();
    const pass = enc.beginComputePass();
    pass.setPipeline(this.pipeline);
    // every centre pass, then the silhouette passes (each dispatch sees the writes before it)
    for (const k of [0, 1]) {
      slots.forEach((s, i) => {
        if (k === 1 && sides[i] < 2) return;
        pass.setBindGroup(0, s.bind[k]);
        pass.dispatchWorkgroups(Math.ceil(s.w / this.wg), Math.ceil(s.h / this.wg));
      });
    }
    pass.end();
    if (target) {
      const rp = enc.beginRenderPass({ colorAttachments: [{ view: target.createView(), loadOp: 'clear', clearValue: { r: 0.12, g: 0.12, b: 0.12, a: 1 }, storeOp: 'store' }] });
      rp.setPipeline(this.presentPipeline(target.format));
      views.forEach((v, i) => {
        const s = slots[i];
        d.queue.writeBuffer(s.screen, 0, new Uint32Array([s.w, s.h, v.x, v.y]));
        if (!s.present) {
          s.present = d.createBindGroup({
            layout: this.presentPipe.getBindGroupLayout(0),
            entries: [{ binding: 0, resource: { buffer: s.screen } }, { binding: 1, resource: { buffer: s.rgba } }],
          });
        }
        rp.setViewport(v.x, v.y, s.w, s.h, 0, 1);
        rp.setBindGroup(0, s.present);
        rp.draw(3);
      });
      rp.end();
    }
    if (capture) {
      for (const s of slots) {
        if (!s.readback) s.readback = d.createBuffer({ size: s.w * s.h * 16, usage: GPUBufferUsage.MAP_READ | GPUBufferUsage.COPY_DST });
        enc.copyBufferToBuffer(s.rgba, 0, s.readback, 0, s.w * s.h * 16);
      }
    }
    d.queue.submit([enc.finish()]);
    this.submittedAt = performance.now();
    if (!capture) { await d.queue.onSubmittedWorkDone(); return null; }
    const out = [];
    for (const s of slots) {
      await s.readback.mapAsync(GPUMapMode.READ);
      out.push(new Float32Array(s.readback.getMappedRange().slice(0)));
      s.readback.unmap();
    }
    return out;
  }
  presentPipeline(format) {
    if (this.presentPipe && this.presentFormat === format) return this.presentPipe;
    this.presentPipe = this.device.createRenderPipeline(presentDescriptor(this.device, this.presentWgsl, format));
    this.presentFormat = format;
    for (const s of this.slots) if (s) s.present = null;
    return this.presentPipe;
  }
}

// shaders/present.wgsl's pipeline drawing into a texture of `format`.
function presentDescriptor(device, wgsl, format) {
  const module = device.createShaderModule({ code: wgsl });
  return {
    layout: 'auto',
    vertex: { module, entryPoint: 'vs' },
    fragment: { module, entryPoint: 'fs', targets: [{ format }] },
    primitive: { topology: 'triangle-list' },
  };
}

// WebGL2 (browsers without WebGPU): the same march, as the fragment shader of /march.glsl
// (shaders/march.wgsl's fragment target translated to GLSL ES 3.00 by the server), drawn as
// a full-screen triangle into float render targets, one pair per view. The same interface
// as `Renderer`; `render`'s target is this renderer's canvas (`gl.canvas`), or null.
// Bindings: GLSL ES 3.00 has no layout(binding), so uniform blocks and samplers are bound by
// the names the translation reports, on the unit / binding point of their WGSL binding.
const GL_BLIT_VS = `#version 300 es
void main() {
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}`;
// A view's target holds image row y at GL row y (see shaders/march_fragment.wgsl): the canvas
// shows it flipped, one texel per pixel, as shaders/present.wgsl does on WebGPU.
const GL_BLIT_FS = `#version 300 es
precision highp float; uniform highp sampler2D img; uniform ivec2 origin; out vec4 o;
void main() {
  ivec2 size = textureSize(img, 0);
  ivec2 p = ivec2(gl_FragCoord.xy) - origin;
  o = vec4(texelFetch(img, ivec2(p.x, size.y - 1 - p.y), 0).rgb, 1.0);
}`;

// A program compiled and linked from `vs` and `fs`; resolves once it is linked. Nothing
// asks for a status before the driver says it is done (KHR_parallel_shader_compile, where
// the browser has it), so the page's thread goes on taking in the stream meanwhile instead
// of blocking on the compile.
async function glProgram(gl, vs, fs, what) {
  const sh = (type, src) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    return s;
  };
  const p = gl.createProgram();
  const shaders = [sh(gl.VERTEX_SHADER, vs), sh(gl.FRAGMENT_SHADER, fs)];
  for (const s of shaders) gl.attachShader(p, s);
  gl.linkProgram(p);
  const par = gl.getExtension('KHR_parallel_shader_compile');
  if (par) while (!gl.getProgramParameter(p, par.COMPLETION_STATUS_KHR)) await new Promise((res) => setTimeout(res, 2));
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) {
    const bad = shaders.find((s) => !gl.getShaderParameter(s, gl.COMPILE_STATUS));
    throw new Error(`${what}: ${bad ? gl.getShaderInfoLog(bad) : gl.getProgramInfoLog(p)}`);
  }
  return p;
}

class RendererGL extends MarchHost {
  // `prog`: the JSON of /march.glsl ({vertex, fragment, uniforms, textures}).
  constructor(gl, h, prog) {
    super(h, gl.getParameter(gl.MAX_3D_TEXTURE_SIZE));
    this.gl = gl;
    this.canvas = gl.canvas;
    const t = this.texels();
    const tex = (target) => {
      const x = gl.createTexture();
      gl.bindTexture(target, x);
      // integer and 32-bit float textures are read by texelFetch only: no filtering, no mips
      gl.texParameteri(target, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
      gl.texParameteri(target, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
      return x;
    };
    this.tex = tex;
    this.atlas = tex(gl.TEXTURE_3D);
    gl.texStorage3D(gl.TEXTURE_3D, 1, h.diffuse ? gl.R32UI : gl.RG32UI, t[0], t[1], t[2]);
    // The grid: entry i at texel (i % width, i / width) of an r32uint texture.
    const n = Math.max(1, this.g3 * this.frames), max = gl.getParameter(gl.MAX_TEXTURE_SIZE);
    this.gridW = Math.min(max, 4096);
    this.gridH = Math.ceil(n / this.gridW);
    if (this.gridH > max) throw new Error(`the grid (${n} entries) does not fit this GPU's 2D textures`);
    this.grid = tex(gl.TEXTURE_2D);
    gl.texStorage2D(gl.TEXTURE_2D, 1, gl.R32UI, this.gridW, this.gridH);
    this.mlpBuf = gl.createBuffer();
    gl.bindBuffer(gl.UNIFORM_BUFFER, this.mlpBuf);
    gl.bufferData(gl.UNIFORM_BUFFER, 900 * 4, gl.DYNAMIC_DRAW);
    // Compiled while the MLP and the grids arrive, as `Renderer`'s pipeline: `pipeline` is
    // null until both programs are linked and bound (`ready()` waits for it).
    this.pipeline = null;
    this.compiled = Promise.all([
      glProgram(gl, prog.vertex, prog.fragment, 'march (GLSL)'),
      glProgram(gl, GL_BLIT_VS, GL_BLIT_FS, 'present (GLSL)'),
    ]).then(([march, blit]) => {
      this.prog = march;
      gl.useProgram(this.prog);
      for (const [b, name] of Object.entries(prog.uniforms)) {
        const i = gl.getUniformBlockIndex(this.prog, name);
        if (i !== gl.INVALID_INDEX) gl.uniformBlockBinding(this.prog, i, +b);
      }
      for (const [b, name] of Object.entries(prog.textures)) gl.uniform1i(gl.getUniformLocation(this.prog, name), +b);
      this.blit = blit;
      this.blitOrigin = gl.getUniformLocation(this.blit, 'origin');
      gl.useProgram(this.blit);
      gl.uniform1i(gl.getUniformLocation(this.blit, 'img'), 0);
      this.pipeline = true;
    });
  }
  setMlp(payload) {
    const gl = this.gl;
    gl.bindBuffer(gl.UNIFORM_BUFFER, this.mlpBuf);
    gl.bufferSubData(gl.UNIFORM_BUFFER, 0, this.mlpRows(payload));
  }
  setBlocks(first, count, data) {
    const gl = this.gl, e = this.edge, n = this.voxelBytes, bb = e * e * e * n;
    gl.bindTexture(gl.TEXTURE_3D, this.atlas);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
    for (let k = 0; k < count; k++) {
      const b = first + k, o = this.origin(b);
      // u32 texels (little-endian, as the file stores a voxel's bytes): a copy when the
      // payload's offset is not 4-aligned
      const bytes = data.subarray(k * bb, (k + 1) * bb);
      const words = bytes.byteOffset % 4 ? new Uint32Array(bytes.slice().buffer) : new Uint32Array(bytes.buffer, bytes.byteOffset, bb / 4);
      gl.texSubImage3D(gl.TEXTURE_3D, 0, o[0], o[1], o[2], e, e, e, n === 8 ? gl.RG_INTEGER : gl.RED_INTEGER, gl.UNSIGNED_INT, words);
      this.present[b] = 1;
    }
    this.gridDirty = true;
  }
  uploadGrid() {
    const gl = this.gl;
    const all = new Uint32Array(this.gridW * this.gridH).fill(EMPTY);
    all.set(this.gridEntries());
    gl.bindTexture(gl.TEXTURE_2D, this.grid);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 4);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, this.gridW, this.gridH, gl.RED_INTEGER, gl.UNSIGNED_INT, all);
    this.gridDirty = false;
  }
  // Targets of one view: pass 0 (every pixel's centre ray) and pass 1 (the silhouette pass,
  // which reads pass 0's as textures), each an rgba32float + r32float pair.
  slot(i, w, hgt) {
    const s0 = this.slots[i];
    if (s0 && s0.w === w && s0.h === hgt) return s0;
    const gl = this.gl;
    const pass = () => {
      const rgba = this.tex(gl.TEXTURE_2D);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.RGBA32F, w, hgt);
      const depth = this.tex(gl.TEXTURE_2D);
      gl.texStorage2D(gl.TEXTURE_2D, 1, gl.R32F, w, hgt);
      const fb = gl.createFramebuffer();
      gl.bindFramebuffer(gl.FRAMEBUFFER, fb);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, rgba, 0);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT1, gl.TEXTURE_2D, depth, 0);
      gl.drawBuffers([gl.COLOR_ATTACHMENT0, gl.COLOR_ATTACHMENT1]);
      const st = gl.checkFramebufferStatus(gl.FRAMEBUFFER);
      if (st !== gl.FRAMEBUFFER_COMPLETE) throw new Error(`WebGL2: float render targets unsupported (status 0x${st.toString(16)})`);
      const params = gl.createBuffer();
      gl.bindBuffer(gl.UNIFORM_BUFFER, params);
      gl.bufferData(gl.UNIFORM_BUFFER, 256, gl.DYNAMIC_DRAW);
      return { rgba, depth, fb, params };
    };
    const s = { w, h: hgt, pass: [pass(), pass()] };
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    if (s0) for (const p of s0.pass) { gl.deleteTexture(p.rgba); gl.deleteTexture(p.depth); gl.deleteFramebuffer(p.fb); gl.deleteBuffer(p.params); }
    return (this.slots[i] = s);
  }
  // As `Renderer.render`: march `views` ([{cam, x, y}]) at `time`, present each into
  // `target` (this renderer's canvas, or null) at (x, y) from its top left; with `capture`,
  // every view read back (Float32Array of width*height RGBA, A = opacity, rows top first).
  // Every GL call is issued before the first await, so a caller that uploads the canvas right
  // after calling (xr.js) gets this frame.
  async render(views, time, target, capture) {
    const gl = this.gl;
    if (this.gridDirty) this.uploadGrid();
    const slots = views.map((v, i) => this.slot(i, v.cam.width, v.cam.height));
    const sides = views.map((v) => this.pixelSide(v.cam));
    this.lastSides = sides;
    gl.disable(gl.BLEND); gl.disable(gl.DEPTH_TEST); gl.disable(gl.SCISSOR_TEST); gl.disable(gl.CULL_FACE);
    gl.useProgram(this.prog);
    gl.activeTexture(gl.TEXTURE5); gl.bindTexture(gl.TEXTURE_3D, this.atlas);
    gl.activeTexture(gl.TEXTURE1); gl.bindTexture(gl.TEXTURE_2D, this.grid);
    gl.bindBufferBase(gl.UNIFORM_BUFFER, 2, this.mlpBuf);
    const final = slots.map((s, i) => {
      for (const k of sides[i] > 1 ? [0, 1] : [0]) {
        const p = s.pass[k], other = s.pass[1 - k];
        gl.bindBuffer(gl.UNIFORM_BUFFER, p.params);
        gl.bufferSubData(gl.UNIFORM_BUFFER, 0, new Uint8Array(this.params(views[i].cam, time, k === 0 ? 0 : sides[i])));
        gl.bindBufferBase(gl.UNIFORM_BUFFER, 0, p.params);
        // pass 1 reads pass 0's output; pass 0 reads nothing there, but a texture bound to a
        // sampler must not be the target being drawn (a feedback loop): pass 1's are bound
        gl.activeTexture(gl.TEXTURE3); gl.bindTexture(gl.TEXTURE_2D, other.rgba);
        gl.activeTexture(gl.TEXTURE4); gl.bindTexture(gl.TEXTURE_2D, other.depth);
        gl.bindFramebuffer(gl.FRAMEBUFFER, p.fb);
        gl.viewport(0, 0, s.w, s.h);
        gl.drawArrays(gl.TRIANGLES, 0, 3);
      }
      return s.pass[sides[i] > 1 ? 1 : 0];
    });
    if (target) {
      gl.bindFramebuffer(gl.FRAMEBUFFER, null);
      gl.viewport(0, 0, gl.drawingBufferWidth, gl.drawingBufferHeight);
      gl.clearColor(0.12, 0.12, 0.12, 1);
      gl.clear(gl.COLOR_BUFFER_BIT);
      gl.useProgram(this.blit);
      gl.activeTexture(gl.TEXTURE0);
      views.forEach((v, i) => {
        const s = slots[i], y = gl.drawingBufferHeight - v.y - s.h; // GL's viewport y is up
        gl.bindTexture(gl.TEXTURE_2D, final[i].rgba);
        gl.uniform2i(this.blitOrigin, v.x, y);
        gl.viewport(v.x, y, s.w, s.h);
        gl.drawArrays(gl.TRIANGLES, 0, 3);
      });
    }
    let out = null;
    if (capture) {
      out = slots.map((s, i) => {
        const px = new Float32Array(s.w * s.h * 4);
        gl.bindFramebuffer(gl.READ_FRAMEBUFFER, final[i].fb);
        gl.readBuffer(gl.COLOR_ATTACHMENT0);
        gl.readPixels(0, 0, s.w, s.h, gl.RGBA, gl.FLOAT, px);
        return px;
      });
      gl.bindFramebuffer(gl.READ_FRAMEBUFFER, null);
    }
    this.submittedAt = performance.now();
    const err = gl.getError();
    if (err !== gl.NO_ERROR) throw new Error(`WebGL2 error 0x${err.toString(16)}`);
    if (!out) await this.finished();
    return out;
  }
  // Resolves once the GPU has done what was submitted (frame timing for the render scale).
  finished() {
    const gl = this.gl, sync = gl.fenceSync(gl.SYNC_GPU_COMMANDS_COMPLETE, 0);
    gl.flush();
    return new Promise((res) => {
      const poll = () => {
        if (gl.getSyncParameter(sync, gl.SYNC_STATUS) === gl.SIGNALED) { gl.deleteSync(sync); res(); } else setTimeout(poll, 1);
      };
      poll();
    });
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

// The full field of view (degrees) of a camera's wider axis: the server's view cone.
const fovOf = (c) => (2 * Math.atan(0.5 * Math.max(c.width / c.fx, c.height / c.fy)) * 180) / Math.PI;

// ---- streaming one asset ----
// The first frame's render scale, as a fraction of the page's (see `stream`).
const FIRST_SCALE = 0.5;
// backendReady: a promise of the renderer, 'webgpu' or 'webgl2'. gpuReady: a promise of the
// GPU, {backend: 'webgpu', device, wg, ctx (the canvas's WebGPU context), present ({wgsl,
// format, pipeline}), target} or {backend: 'webgl2', gl (the canvas's WebGL2 context),
// target}; target(): what a frame of the page's canvas is presented into. The session opens
// while the GPU is being set up; the header's shader fetch waits for the backend only, the
// renderer for the GPU. firstConfig: a promise of /config.json as read at start.
// onFirstFrame: called once the first frame is drawn.
async function stream(name, backendReady, gpuReady, firstConfig, onFirstFrame) {
  const t0 = performance.now();
  let gpu = null;
  // Orbit state; `pan` moves the orbit centre (keyboard fly), in world units.
  const view = { yaw: 0, pitch: null, radius: null, pan: [0, 0, 0] };
  let time = frag.has('time') ? parseFloat(frag.get('time')) : 0;
  let h = null, r = null, orbit = null;
  const chunks = [];
  // The style switch in progress (switchStyle), if any, and the blocks it recoloured that
  // are not uploaded yet.
  let switching = null, fadeFrom = false, fadeValid = false;
  const recoloured = new Set();
  function flushRecoloured() {
    if (!recoloured.size) return;
    for (const b of recoloured) r.setBlocks(b, 1, chunks[blkChunk[b]].subarray(20));
    recoloured.clear();
  }
  let finish, abort;
  const complete = new Promise((res, rej) => { finish = res; abort = rej; });
  let seq = 0, dgram = null;
  // Tests read every frame back (a fixed camera, or capture=1 in the fragment).
  const capture = !!fixedCam || frag.has('capture');
  // Render scale: the fraction of the canvas's device pixels marched, chosen each frame to
  // hold the display's frame rate while the view moves; a still view is refined at 1.
  // The first frames start small (frame rate first) and grow while frames are fast.
  let scale = fixedCam ? 1 : 0.25, refined = false, lastInput = -1e9, playing = false, lastTick = null, lastScaled = -1e9;
  const rafTimes = [];

  function refreshMs() {
    if (rafTimes.length < 8) return 1000 / 60;
    const d = rafTimes.slice(1).map((t, i) => t - rafTimes[i]).sort((a, b) => a - b);
    return d[d.length >> 1];
  }
  function renderSize(sc) {
    const cv = $('canvas'), dpr = window.devicePixelRatio || 1;
    const w = Math.max(16, Math.round((cv.clientWidth || 640) * dpr * sc));
    const hh = Math.max(16, Math.round((cv.clientHeight || 480) * dpr * sc));
    return [w, hh];
  }
  function camera(sc) {
    if (fixedCam) return fixedCam;
    const o = orbit;
    const el = view.pitch ?? o.elevation;
    const rad = view.radius ?? o.radius;
    const side = cross(o.up, o.start);
    const horiz = add(scl(o.start, Math.cos(view.yaw)), scl(side, Math.sin(view.yaw)));
    const dir = add(scl(horiz, Math.cos(el)), scl(o.up, Math.sin(el)));
    const c = add(o.center, view.pan);
    const c2w = lookAt(add(c, scl(dir, rad)), c, o.up);
    const [w, hh] = renderSize(sc);
    const f = (0.5 * hh) / Math.tan((0.5 * 40 * Math.PI) / 180);
    return { c2w, fx: f, fy: f, cx: w / 2, cy: hh / 2, width: w, height: hh, lodFx: f / sc };
  }
  // The 40-byte pose datagram (PROTOCOL.md): eye, forward (world), playback time, field of
  // view in degrees. The flat page's orbit camera and the XR head both go through it.
  function sendPoseRaw(eye, fwd, fov) {
    if (!dgram) return;
    const b = new ArrayBuffer(40), dv = new DataView(b);
    dv.setUint8(0, 0x53); dv.setUint8(1, 0x50); dv.setUint8(2, 1); dv.setUint8(3, 0);
    dv.setUint32(4, ++seq, true);
    [...eye, ...fwd, time, fov].forEach((v, i) => dv.setFloat32(8 + 4 * i, v, true));
    dgram.write(new Uint8Array(b)).catch(() => {});
    report.posesSent = seq;
    report.lastPose = { eye, forward: fwd, fov };
  }
  function sendPose() {
    if (!orbit || xrActive) return;
    const c = camera(scale);
    sendPoseRaw([c.c2w[0][3], c.c2w[1][3], c.c2w[2][3]], [-c.c2w[0][2], -c.c2w[1][2], -c.c2w[2][2]], fovOf(c));
  }

  // The pose goes in the hello when it is known already (a fixed camera), so the very first
  // blocks sent are the ones in view; otherwise by datagram as soon as the header is in.
  const hello = { type: 'hello', version: 1, token, asset: name, have: [] };
  if (fixedCam) {
    const c = fixedCam;
    hello.pose = {
      eye: [c.c2w[0][3], c.c2w[1][3], c.c2w[2][3]], forward: [-c.c2w[0][2], -c.c2w[1][2], -c.c2w[2][2]],
      time, fov_deg: fovOf(c),
    };
  }
  let { wt, ctl } = await connect(hello, firstConfig);
  report.connectedAt = performance.now();
  report.marks.connected = report.connectedAt;
  const welcome = await readMsg(ctl);
  report.marks.welcome = performance.now();
  if (welcome.type !== 'welcome' || !welcome.asset) throw new Error('no asset in the welcome');
  // (another style's once a style switch has written its colour over this one)
  let info = welcome.asset;
  report.asset = info;
  report.state = 'streaming';
  // Blocks in the order they were applied, and the stream each came on (numbered as the
  // page accepted them). Streams are read concurrently, so records of two streams in flight
  // may be applied interleaved; by stream, then in order, is the order the server sent.
  report.arrivals = [];
  report.arrivalStreams = [];
  let streamsAccepted = 0;
  report.resumes = 0;
  dgram = wt.datagrams.writable.getWriter();
  const poseTimer = setInterval(sendPose, 250);

  let busy = false, dirty = false;
  // The small parts (MLP, grids) are in; `ready`: and the pipeline is compiled.
  const partsIn = () => r && r.mlp && r.grids.every((g) => g);
  const ready = () => partsIn() && r.pipeline;
  // One frame: march at the current scale, present to the canvas (and read back if asked).
  async function frameNow(sc) {
    if (busy || !ready()) return;
    busy = true;
    dirty = false;
    try {
      const cam = camera(sc);
      const cv = $('canvas');
      if (cv.width !== cam.width || cv.height !== cam.height) { cv.width = cam.width; cv.height = cam.height; }
      if (fixedCam) {
        // One canvas pixel per device pixel, so a screenshot of the canvas is the frame.
        const dpr = window.devicePixelRatio || 1;
        cv.style.width = `${cam.width / dpr}px`; cv.style.height = `${cam.height / dpr}px`; cv.style.aspectRatio = 'auto';
      }
      // What this frame shows: the blocks uploaded before it was submitted (and of a style
      // switch, the colour records written).
      flushRecoloured();
      const sw = switching, applied = sw ? sw.applied : 0;
      const blocks = report.blocks, done = report.chunks === info.chunks && (!sw || applied === sw.records);
      const ts = performance.now();
      const drawn = r.render([{ cam, x: 0, y: 0 }], time, gpu.target(), capture);
      // What a style switch fades from: the still view's full-resolution frame, kept as it is
      // drawn (the view a key is pressed on), or, when the view has changed since, the first
      // frame after the key (still the old style). Copied in this task, while the canvas
      // holds the frame: a WebGPU canvas reads back empty once presented.
      if (fadeFrom) { fadeFrom = false; if (!applied) { copyToFade(); showFade(); } }
      else if (!sw && sc === 1 && done) { copyToFade(); fadeValid = true; } else fadeValid = false;
      const out = await drawn;
      const ms = performance.now() - ts;
      report.frames++;
      if (sw && applied > 0 && !sw.firstFrameAt) {
        sw.firstFrameAt = performance.now();
        sw.firstFrameRecords = applied;
        fadeOut();
      }
      if (sw && applied === sw.records && !sw.completeAt) sw.completeAt = performance.now();
      const first = report.firstFrameMs === null;
      if (first) {
        report.marks.submitted = r.submittedAt;
        report.marks.firstFrame = performance.now();
        report.firstFrameMs = performance.now() - t0;
        report.firstFrameAt = performance.now();
        report.firstFrame = { width: cam.width, height: cam.height, blocks, complete: done };
      }
      report.lastFrame = { width: cam.width, height: cam.height, complete: done, ms, scale: sc, pixelSides: r.lastSides };
      if (out) report.lastRender = { rgba: out[0], width: cam.width, height: cam.height, complete: done };
      if (done && !report.completeAt) report.completeAt = performance.now();
      // The first frame's time is mostly one-time work (the GPU's first use of the
      // pipelines and the atlas): it says nothing about the frame rate.
      if (sc === scale && !fixedCam && !first) adapt(ms);
      stats(ms, sc);
      if (first && onFirstFrame) onFirstFrame();
    } catch (e) { fail(e); }
    busy = false;
  }
  function adapt(ms) {
    const k = Math.sqrt((0.9 * refreshMs()) / Math.max(ms, 0.1));
    if (k < 0.95 || (k > 1.1 && scale < 1)) scale = Math.min(1, Math.max(0.1, scale * Math.min(1.25, Math.max(0.6, k))));
  }
  const redraw = () => { dirty = true; };
  const touched = () => { lastInput = performance.now(); refined = false; sendPose(); };
  function tick(now) {
    rafTimes.push(now);
    if (rafTimes.length > 32) rafTimes.shift();
    requestAnimationFrame(tick);
    if (xrActive) return; // the XR session's own frame loop draws
    if (playing) { advance((now - (lastTick ?? now)) / 1000); dirty = true; }
    lastTick = now;
    const moving = playing || now - lastInput < 300;
    if (fixedCam) { if (dirty) frameNow(1); return; }
    // Every frame at the adaptive scale leaves the view to be refined; the refinement (full
    // resolution) comes once nothing has changed for a moment, and only when it can draw
    // (before the scene is renderable a refinement would be spent on nothing).
    if (moving || dirty) { refined = false; lastScaled = now; frameNow(scale); }
    // (not while a style switch streams: a full-resolution march would hold back its frames)
    else if (!refined && !busy && ready() && !switching && now - lastScaled > 250) { refined = true; frameNow(1); }
  }
  requestAnimationFrame(tick);

  // What the immersive mode (xr.js) uses of this stream.
  function togglePlay() {
    if (!h || !h.frames || h.frames.length < 2) return;
    playing = !playing;
    $('play').textContent = playing ? 'pause' : 'play';
    lastTick = null;
  }
  function advance(dt) {
    if (!playing || !h || !h.frames) return;
    const lo = h.frames[0].time, hi = h.frames[h.frames.length - 1].time;
    time += dt;
    if (time > hi) time = lo + ((time - lo) % Math.max(hi - lo, 1e-6));
    $('time').value = time;
  }
  const api = {
    gpu: null, capture, ready, fixedScale: frag.has('xrscale') ? parseFloat(frag.get('xrscale')) : null, hold: frag.has('xrhold'), togglePlay, advance, sendPose: sendPoseRaw,
    renderer: () => r, header: () => h, orbit: () => orbit, time: () => time,
    playing: () => playing,
    setXR: (on) => { xrActive = on; if (!on) { dirty = true; refined = false; } },
  };
  // Enter VR is offered once the header is in (placement comes from it).
  const xrModule = import('./xr.js');
  const xrOk = xrModule.then((m) => m.xrSupported());
  const offerXR = () => xrOk.then((ok) => {
    if (!ok) return;
    const b = $('xr');
    b.hidden = false;
    b.onclick = () => {
      report.xrClickAt = performance.now();
      xrModule.then((m) => m.enterXR(api, report)).catch((e) => { report.xr = { ...(report.xr || {}), state: 'error', error: String(e.message || e) }; setStatus('VR: ' + (e.message || e)); });
    };
  });

  function stats(ms, sc) {
    $('stats').textContent =
      `${(1000 / Math.max(ms, 0.01)).toFixed(1)} fps (${ms.toFixed(1)} ms)  scale ${sc.toFixed(2)}  ${report.backend}\n` +
      `blocks ${report.blocks}/${h ? h.atlas_blocks : '?'}  chunks ${report.chunks}/${info.chunks}\n` +
      `${(report.bytes / 1048576).toFixed(2)} MiB received\n` +
      `first frame ${report.firstFrameMs === null ? '-' : report.firstFrameMs.toFixed(0) + ' ms'}`;
  }

  async function onChunk(index, ck, stream) {
    const tag = td.decode(ck.subarray(0, 4));
    const p = ck.subarray(12);
    if (chunks[index]) return;
    if (!r && tag !== 'HEAD') { pendingChunks.push([index, ck, stream]); return; }
    chunks[index] = ck;
    report.chunks++;
    if (report.chunks === info.chunks) finish();
    if (tag === 'HEAD') {
      report.marks.header = performance.now();
      h = JSON.parse(td.decode(p));
      orbit = orbitOf(h);
      view.elevation = orbit.elevation;
      view.baseRadius = orbit.radius;
      const kind = { object: 0, forward: 1, unbounded: 2 }[h.kind];
      const dyn = h.frames && h.frames.length > 1 ? 1 : 0;
      const variant = `kind=${kind}&dynamic=${dyn}&diffuse=${h.diffuse ? 1 : 0}&block=${h.block}`;
      // The same march either way: the compute shader (WebGPU) or its fragment target in GLSL
      // (WebGL2), both composed by the server from shaders/march.wgsl.
      // The renderer is known once the adapter is (or is not); its device may still be in the
      // making while the shader is fetched. A header that comes before the adapter's answer
      // (a browser without WebGPU can take a few hundred ms to say so) has both texts fetched
      // at once, tens of KB, rather than the fetch waiting for that answer.
      const url = (b) => `/march.${b === 'webgl2' ? 'glsl' : 'wgsl'}?${variant}`;
      const get = (b) => (manifestUrl ? publishedFile(`march.${b === 'webgl2' ? 'glsl' : 'wgsl'}`) : fetch(url(b)));
      const early = report.backend ? null : { webgpu: get('webgpu'), webgl2: get('webgl2') };
      if (early) for (const f of Object.values(early)) f.catch(() => {}); // the one not used
      const backend = await backendReady;
      const res = await (early ? early[backend] : get(backend));
      gpu = api.gpu = await gpuReady;
      if (!res.ok) throw new Error('shader: HTTP ' + res.status);
      if (gpu.backend === 'webgl2') {
        const prog = await res.json();
        report.marks.shader = performance.now();
        r = new RendererGL(gpu.gl, h, prog);
      } else {
        const code = await res.text();
        report.marks.shader = performance.now();
        r = new Renderer(gpu.device, h, code, gpu.present, gpu.wg);
      }
      // Compiling while the rest comes in; awaited (failures too) before the first frame.
      r.compiled.then(() => { report.marks.pipeline = performance.now(); }, () => {});
      // a diffuse asset has no VMLP chunk: its view MLP is zero
      if (h.diffuse) { r.setMlp(new Uint8Array(883 * 4)); r.mlp = true; }
      sendPose();
      offerXR();
      if (dyn) {
        const tb = $('time');
        tb.min = h.frames[0].time; tb.max = h.frames[h.frames.length - 1].time; tb.value = time;
        $('timebox').hidden = false;
        tb.oninput = () => { time = parseFloat(tb.value); sendPose(); redraw(); };
        $('play').onclick = togglePlay;
      }
      for (const q of pendingChunks.splice(0)) await onChunk(q[0], q[1], q[2]);
    } else if (tag === 'VMLP') { r.setMlp(p); r.mlp = true; }
    else if (tag === 'GRID') { r.setGrid(u32(p, 0), new Uint32Array(p.slice(4).buffer)); }
    else if (tag === 'SGRD') {
      // a sparse grid (FORMAT.md, version 5): (cell, entry) pairs, every other cell empty
      const grid = new Uint32Array(r.g3).fill(EMPTY);
      for (let k = 0, n = u32(p, 4); k < n; k++) grid[u32(p, 8 + 8 * k)] = u32(p, 12 + 8 * k);
      r.setGrid(u32(p, 0), grid);
    }
    else if (tag === 'BLKS') {
      const first = u32(p, 0), n = u32(p, 4);
      r.setBlocks(first, n, p.subarray(8));
      report.blocks += n;
      if (report.arrivals.length < 65536) { report.arrivals.push(index); report.arrivalStreams.push(stream); }
    }
    if (partsIn()) {
      // The first frame is drawn as soon as the small parts are in and the pipeline is
      // compiled, before more blocks are taken in (chunks are applied one at a time):
      // progressive from the first block on. It is marched at a fraction of the render
      // scale (FIRST_SCALE: a quarter of its pixels): the page shows the scene sooner, and
      // the next frames are marched at the render scale.
      if (report.firstFrameMs === null) {
        await r.compiled;
        if (!report.marks.ready) report.marks.ready = performance.now();
        dirty = true;
        await frameNow(fixedCam ? 1 : scale * FIRST_SCALE);
      } else redraw();
    }
  }
  const pendingChunks = [];

  // Records: u32 chunk index, then the chunk (tag, u32 length, u32 CRC-32, payload).
  let queue = Promise.resolve();
  let received = 0; // distinct chunks whose whole record was read off a stream
  const got = new Uint8Array(info.chunks);
  async function readStream(s, stream) {
    const rd = new Reader(s);
    for (;;) {
      const head = await rd.take(16);
      if (!head) return;
      const index = u32(head, 0), len = u32(head, 8), crc = u32(head, 12);
      if (index >= info.chunks || len > info.size) throw new Error(`bad record for chunk ${index}`);
      const payload = len ? await rd.take(len) : new Uint8Array(0);
      if (!payload && len) throw new Error('stream ended inside a record');
      const tc = performance.now();
      const bad = crc32(payload) !== crc;
      report.crcMs += performance.now() - tc;
      if (bad) throw new Error(`chunk ${index}: checksum mismatch`);
      const ck = new Uint8Array(12 + len);
      ck.set(head.subarray(4)); ck.set(payload, 12);
      report.bytes += 16 + len;
      if (got[index]) continue;
      got[index] = 1;
      received++;
      if (received === info.chunks) report.downloadedAt = performance.now();
      queue = queue.then(() => onChunk(index, ck, stream)).catch(abort);
    }
  }
  if (!fixedCam) attachControls(view, () => orbit, touched);
  $('view').hidden = false;
  setStatus(`streaming ${info.name}: ${info.size} bytes in ${info.chunks} chunks`);

  // The server closes a session some time after everything was acknowledged; by then every
  // record is here even if not yet applied, and that is no failure. A session lost earlier
  // is resumed (PROTOCOL.md, "Resume"): a new session whose hello lists the chunks held
  // (`have`, for this file's SHA-256), so only the rest is sent; a few tries, backing off.
  const RESUME_TRIES = 6;
  let tries = 0, resuming = false, current = wt;
  const haveRanges = () => {
    const out = [];
    for (let i = 0; i < got.length; i++) {
      if (!got[i]) continue;
      if (out.length && out[out.length - 1][1] === i) out[out.length - 1][1] = i + 1; else out.push([i, i + 1]);
    }
    return out;
  };
  function attach(w) {
    current = w;
    const lost = (e) => ended(w, e);
    w.closed.then(
      (i) => ended(w, new Error(`the server closed the session (code ${i.closeCode}: ${i.reason})`), i.closeCode),
      (e) => ended(w, new Error(`the session failed: ${e.message || e}`)),
    );
    (async () => {
      const uni = w.incomingUnidirectionalStreams.getReader();
      for (;;) {
        const { value, done } = await uni.read();
        if (done) return;
        readStream(value, streamsAccepted++).catch(lost);
      }
    })().catch(lost);
  }
  function ended(w, e, code) {
    if (received >= info.chunks || w !== current || resuming) return;
    // Refusals (bad token, no such asset, ...) are final; a lost connection is not.
    if (code !== undefined && ![0, 6, 7, 10].includes(code)) { abort(e); return; }
    if (tries >= RESUME_TRIES) { abort(e); return; }
    resuming = true;
    const delay = 250 * 2 ** tries++;
    setStatus(`connection lost; resuming in ${delay} ms (${received} of ${info.chunks} chunks held)`);
    setTimeout(async () => {
      try {
        const have = haveRanges();
        const held = have.reduce((n, [a, b]) => n + b - a, 0);
        const c = await connect({ ...hello, have, resume_id: info.sha256 });
        const wel = await readMsg(c.ctl);
        if (wel.type !== 'welcome' || !wel.asset || wel.asset.sha256 !== info.sha256) throw new Error('the asset changed on the server');
        report.resumes++;
        report.lastResume = { resumed: wel.resumed, sending_chunks: wel.sending_chunks, held };
        dgram = c.wt.datagrams.writable.getWriter();
        resuming = false;
        attach(c.wt);
        sendPose();
        setStatus(`resumed: ${wel.sending_chunks} chunks to come`);
      } catch (err) {
        resuming = false;
        ended(current, err);
      }
    }, delay);
  }
  attach(wt);
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
  try { current.close({ closeCode: 0, reason: 'done' }); } catch { /* already closed */ }
  report.completeMs = performance.now() - t0;
  redraw();
  // Wait for the complete frame (in VR the session draws it: no flat frame comes).
  while (!xrActive && (!report.lastFrame || !report.lastFrame.complete || busy || dirty)) await new Promise((res) => setTimeout(res, 10));
  // Benchmarks (snerf bench web): n frames of the current view, each timed from submission
  // to the GPU finishing (ms).
  // Style switches (PROTOCOL.md, "Style switches"): another style of this multi-style file
  // by its colour part alone, written over the blocks held (Recolour); the density stays.
  // The old style's last frame stays on screen over the canvas and fades out over 0.3 s from
  // the first frame with new colour on, while the rest streams.
  report.switches = [];
  let recolour = null;
  const blkChunk = new Uint32Array(info.atlas_blocks);
  let oneBlockEach = true;
  chunks.forEach((ck, i) => {
    if (td.decode(ck.subarray(0, 4)) !== 'BLKS') return;
    if (u32(ck, 16) !== 1) oneBlockEach = false; else blkChunk[u32(ck, 12)] = i;
  });
  const vmlpChunk = chunks.findIndex((ck) => td.decode(ck.subarray(0, 4)) === 'VMLP');
  async function switchStyle(name, pressAt) {
    const sw = { name, pressAt, applied: 0, records: null, bytes: 0, state: 'connecting' };
    report.switches.push(sw);
    if (fadeValid) showFade(); else { fadeFrom = true; redraw(); }
    const c = camera(fixedCam ? 1 : scale);
    const hello2 = {
      type: 'hello', version: 1, token, asset: name, have: [], colour_of: info.geometry,
      pose: { eye: [c.c2w[0][3], c.c2w[1][3], c.c2w[2][3]], forward: [-c.c2w[0][2], -c.c2w[1][2], -c.c2w[2][2]], time, fov_deg: fovOf(c) },
    };
    const { wt: w2, ctl: c2 } = await connect(hello2);
    try {
      const wel = await readMsg(c2);
      sw.welcomeAt = performance.now();
      if (wel.type !== 'welcome' || !wel.colour_only || !wel.asset || wel.asset.geometry !== info.geometry || wel.asset.atlas_blocks !== info.atlas_blocks) {
        throw new Error(`the server did not answer the switch to ${name} by colour`);
      }
      sw.records = wel.sending_chunks;
      sw.state = 'streaming';
      if (!recolour) recolour = new Recolour(h, r.grids[0], chunks, blkChunk, r.voxelBytes);
      recolour.have.fill(0);
      switching = sw;
      dgram = w2.datagrams.writable.getWriter();
      let done;
      const all = new Promise((res) => { done = res; });
      let q = Promise.resolve();
      const apply = (index, tag, p) => {
        if (tag === 'SMLP') {
          if (index !== vmlpChunk || p.length !== 4 + 883 * 4) throw new Error('a view MLP record that does not fit');
          r.setMlp(p.subarray(4));
          const ck = new Uint8Array(12 + p.length - 4);
          ck.set(chunks[index].subarray(0, 8)); ck.set(p.subarray(4), 12);
          chunks[index] = ck;
        } else if (tag === 'SCOL') {
          if (blkChunk[u32(p, 4)] !== index) throw new Error(`colour of block ${u32(p, 4)} under chunk ${index}`);
          // uploaded once per frame (flushRecoloured): a block's neighbours change with it
          for (const b of recolour.apply(p)) recoloured.add(b);
        } else throw new Error(`a ${tag} record in a switch`);
        sw.applied++;
        if (sw.applied === 1) sw.firstRecordAt = performance.now();
        redraw();
        if (sw.applied === sw.records) done();
      };
      const readColour = async (st) => {
        const rd = new Reader(st);
        for (;;) {
          const head = await rd.take(16);
          if (!head) return;
          const index = u32(head, 0), len = u32(head, 8), crc = u32(head, 12);
          if (index >= info.chunks || len > info.size) throw new Error(`bad record for chunk ${index}`);
          const p = len ? await rd.take(len) : new Uint8Array(0);
          if (crc32(p) !== crc) throw new Error(`chunk ${index}: checksum mismatch`);
          sw.bytes += 16 + len;
          const tag = td.decode(head.subarray(4, 8));
          q = q.then(() => apply(index, tag, p));
          // a record that does not fit fails the switch (the server sends no END to wait for)
          q.catch(applyFailed);
        }
      };
      let applyFailed;
      const failed = new Promise((_, rej) => {
        applyFailed = rej;
        w2.closed.then((i) => rej(new Error(`the server closed the switch (code ${i.closeCode}: ${i.reason})`)), (e) => rej(e));
        (async () => {
          const uni = w2.incomingUnidirectionalStreams.getReader();
          for (;;) {
            const { value, done: end } = await uni.read();
            if (end) return;
            readColour(value).catch(rej);
          }
        })().catch(rej);
      });
      failed.catch(() => {});
      if (sw.records > 0) await Promise.race([all, failed]);
      await q;
      sw.receivedAt = performance.now();
      try { w2.close({ closeCode: 0, reason: 'done' }); } catch { /* closed */ }
      // The new style's file, end to end: its chunks (CRCs of the rewritten ones anew) hash
      // to the server's SHA-256 of that style.
      for (let k = 0; k < info.atlas_blocks; k++) {
        const ck = chunks[blkChunk[k]];
        new DataView(ck.buffer, ck.byteOffset).setUint32(8, crc32(ck.subarray(12)), true);
      }
      if (vmlpChunk >= 0) new DataView(chunks[vmlpChunk].buffer, chunks[vmlpChunk].byteOffset).setUint32(8, crc32(chunks[vmlpChunk].subarray(12)), true);
      const parts = [unhex(wel.asset.preamble), ...chunks];
      const file = new Uint8Array(parts.reduce((a, b) => a + b.length, 0));
      let o = 0;
      for (const part of parts) { file.set(part, o); o += part.length; }
      const sha = hex(new Uint8Array(await crypto.subtle.digest('SHA-256', file)));
      if (sha !== wel.asset.sha256) throw new Error(`after the switch to ${name} the SHA-256 is ${sha}, the server's is ${wel.asset.sha256}`);
      info = wel.asset;
      report.asset = info; report.sha256 = sha;
      sw.state = 'done';
      setStatus(`${info.name}: switched by its colour (${sw.bytes} bytes), SHA-256 verified`);
      // the complete view: a frame drawn after the last record
      redraw();
      while (!sw.completeAt && !xrActive) await new Promise((res) => setTimeout(res, 5));
    } catch (e) {
      sw.state = 'error'; sw.error = String(e.message || e);
      fadeOut();
      try { w2.close({ closeCode: 0, reason: 'done' }); } catch { /* closed */ }
      throw e;
    } finally {
      if (switching === sw) switching = null;
      dgram = null;
    }
  }
  // The switch's tables (live and stored voxels, apron holders) depend on the geometry
  // alone: made once, while the page is idle, rather than after the first press.
  if (info.geometry && oneBlockEach) {
    (window.requestIdleCallback || setTimeout)(() => {
      if (!recolour) recolour = new Recolour(h, r.grids[0], chunks, blkChunk, r.voxelBytes);
      report.switchReady = true;
    }, { timeout: 1000 });
  }
  let queued = null, inFlight = false;
  active = {
    // Whether `name` is another style of this file that a switch by colour can reach.
    canSwitch: (name) => !!info.geometry && oneBlockEach && (vmlpChunk >= 0) === !h.diffuse && report.transport === 'webtransport' &&
      !!report.styles && report.styles.includes(name),
    current: () => (queued ? queued[0] : switching ? switching.name : info.name),
    switchTo: async (name) => {
      const pressAt = performance.now();
      if (inFlight) { queued = [name, pressAt]; return; }
      inFlight = true;
      try {
        for (let next = [name, pressAt]; next; next = queued, queued = null) await switchStyle(next[0], next[1]);
      } finally { inFlight = false; }
    },
  };
  report.benchFrames = async (n, cam0) => {
    const out = [];
    for (let i = 0; i < n; i++) {
      const cam = cam0 || camera(fixedCam ? 1 : scale);
      const t = performance.now();
      await r.render([{ cam, x: 0, y: 0 }], time, gpu.target(), false);
      out.push(performance.now() - t);
    }
    return out;
  };
  return info;
}

// Mouse, touch and keyboard: drag (one pointer) orbits, wheel or pinch (two pointers) zooms,
// WASD moves the orbit centre in the view's horizontal plane, Q/E along up, arrows orbit.
function attachControls(view, orbit, changed) {
  const cv = $('canvas');
  const pts = new Map();
  let pinch = null;
  const zoom = (f) => { const o = orbit(); if (o) { view.radius = (view.radius ?? o.radius) * f; changed(); } };
  const turn = (dx, dy) => {
    const o = orbit();
    if (!o) return;
    view.yaw -= dx;
    view.pitch = Math.max(-1.5, Math.min(1.5, (view.pitch ?? o.elevation) + dy));
    changed();
  };
  cv.addEventListener('pointerdown', (e) => { pts.set(e.pointerId, [e.clientX, e.clientY]); cv.setPointerCapture(e.pointerId); pinch = null; });
  const up = (e) => { pts.delete(e.pointerId); pinch = null; };
  cv.addEventListener('pointerup', up);
  cv.addEventListener('pointercancel', up);
  cv.addEventListener('pointermove', (e) => {
    const last = pts.get(e.pointerId);
    if (!last) return;
    pts.set(e.pointerId, [e.clientX, e.clientY]);
    if (pts.size === 1) { turn((e.clientX - last[0]) * 0.01, (e.clientY - last[1]) * 0.01); return; }
    const [a, b] = [...pts.values()];
    const d = Math.hypot(a[0] - b[0], a[1] - b[1]);
    if (pinch) zoom(pinch / Math.max(d, 1));
    pinch = d;
  });
  cv.addEventListener('wheel', (e) => { e.preventDefault(); zoom(Math.exp(e.deltaY * 0.001)); }, { passive: false });
  window.addEventListener('keydown', (e) => {
    const o = orbit();
    if (!o || e.target.tagName === 'INPUT') return;
    const k = e.key.toLowerCase();
    const step = 0.05 * (view.radius ?? o.radius);
    // Camera-relative directions in the horizontal plane (see camera()).
    const side = cross(o.up, o.start);
    const fwd = scl(add(scl(o.start, Math.cos(view.yaw)), scl(side, Math.sin(view.yaw))), -1);
    const right = cross(fwd, o.up);
    const mv = { w: fwd, s: scl(fwd, -1), d: right, a: scl(right, -1), e: o.up, q: scl(o.up, -1) }[k];
    if (mv) { view.pan = add(view.pan, scl(mv, step)); changed(); return; }
    const rot = { arrowleft: [0.1, 0], arrowright: [-0.1, 0], arrowup: [0, 0.1], arrowdown: [0, -0.1] }[k];
    if (rot) { e.preventDefault(); turn(rot[0], rot[1]); }
  });
}

// A listing thumbnail (RGB8, base64) on a small canvas.
function thumbCanvas(t) {
  const c = document.createElement('canvas');
  c.width = t.width; c.height = t.height; c.className = 'thumb';
  const rgb = Uint8Array.from(atob(t.rgb), (ch) => ch.charCodeAt(0));
  const img = new ImageData(t.width, t.height);
  for (let i = 0; i < t.width * t.height; i++) {
    img.data.set(rgb.subarray(3 * i, 3 * i + 3), 4 * i);
    img.data[4 * i + 3] = 255;
  }
  c.getContext('2d').putImageData(img, 0, 0);
  return c;
}

function showListing(assets) {
  report.listing = assets;
  const tbody = $('assets').querySelector('tbody');
  for (const a of assets) {
    const tr = document.createElement('tr');
    const tdT = document.createElement('td');
    if (a.thumb) tdT.appendChild(thumbCanvas(a.thumb));
    tr.appendChild(tdT);
    for (const v of [a.name, `${(a.size / 1048576).toFixed(2)} MiB`, a.kind || '?']) {
      const td_ = document.createElement('td'); td_.textContent = v; tr.appendChild(td_);
    }
    const b = document.createElement('button');
    b.textContent = 'view';
    b.onclick = () => viewAsset(a.name);
    const td2 = document.createElement('td'); td2.appendChild(b); tr.appendChild(td2);
    // A multi-style asset: a swatch per style (its header's mean colour); the server streams
    // style S of asset A as `A.S`. Keys 1..9 switch the asset on screen to its styles.
    const td3 = document.createElement('td');
    td3.className = 'styles';
    tr.appendChild(td3);
    swatchRow.set(a.name, td3);
    const td4 = document.createElement('td');
    td4.className = 'offer';
    tr.appendChild(td4);
    offerRow.set(a.name, td4);
    if (a.styles) showSwatches(a.name, a.styles);
    tbody.appendChild(tr);
  }
  return assets;
}

// The swatch cell and the offer cell of each listed asset, by name.
const swatchRow = new Map();
const offerRow = new Map();
// The watching session's control stream writer, while it lasts (`add_style` goes on it).
let watchWriter = null;

// The paintings the server offers to train as new styles of `asset` (PROTOCOL.md, "New
// styles"): a choice and a button that asks for it; the new style's swatch comes when it is
// added. Keys of installed paintings only: the page never sends a file.
function showOffer(asset, paintings) {
  const td = offerRow.get(asset);
  if (!td) return;
  td.replaceChildren();
  if (!paintings || !paintings.length || !watchWriter) return;
  const sel = document.createElement('select');
  sel.className = 'paintings';
  for (const k of paintings) {
    const o = document.createElement('option');
    o.value = k; o.textContent = k;
    sel.appendChild(o);
  }
  const b = document.createElement('button');
  b.className = 'train'; b.textContent = 'train style';
  b.onclick = () => {
    if (!watchWriter) return;
    b.disabled = true;
    watchWriter.write(frame({ type: 'add_style', asset, painting: sel.value })).catch(() => {});
  };
  td.append(sel, b);
}
function showSwatches(asset, styles) {
  const td3 = swatchRow.get(asset);
  if (!td3) return;
  td3.replaceChildren();
  styles.forEach((st, i) => {
    const sw = document.createElement('button');
    sw.className = 'swatch'; sw.textContent = String(i + 1); sw.title = st.name;
    sw.style.background = `rgb(${st.swatch.map((c) => Math.round(255 * Math.min(Math.max(c, 0), 1))).join(',')})`;
    sw.onclick = () => viewAsset(`${asset}.${st.name}`);
    td3.appendChild(sw);
  });
  const shown = frag.get('asset');
  if (shown === asset || (shown && shown.startsWith(asset + '.') && styles.some((st) => shown === `${asset}.${st.name}`))) {
    report.styles = styles.map((st) => `${asset}.${st.name}`);
  }
}

// New styles (PROTOCOL.md, "New styles"): a session of its own that lists with `watch` and
// is then sent an asset's style list each time the server adds a style to it (`snerf serve
// --styles-dir`); the asset's row gets the new swatch and, for the asset on screen, the keys
// reach it (a switch to it goes by colour, as to any other). The paintings the server offers
// are asked for on this session (`showOffer`). WebTransport only: over HTTPS an
// answer ends with its request. A lost session is opened again (the server restarting), up
// to 5 times in a row.
async function watchStyles() {
  for (let failures = 0; failures < 5; failures++) {
    try {
      const { wt, writer, ctl } = await connect({ type: 'hello', version: 1, token, asset: null });
      try {
        const welcome = await readMsg(ctl);
        if (welcome.type !== 'welcome') throw new Error('unexpected ' + welcome.type);
        await writer.write(frame({ type: 'list', watch: true }));
        const listing = await readMsg(ctl);
        if (listing.type !== 'listing') throw new Error('unexpected ' + listing.type);
        watchWriter = writer;
        // what changed while no session watched, and what the server offers to train
        const offered = new Map(listing.assets.map((a) => [a.name, a.paintings || []]));
        for (const a of listing.assets) {
          if (a.styles) showSwatches(a.name, a.styles);
          showOffer(a.name, offered.get(a.name));
        }
        report.watching = true;
        failures = 0;
        for (;;) {
          const m = await readMsg(ctl);
          if (m.type === 'training') {
            report.training = `${m.asset}.${m.style}`;
            setStatus(`${m.asset}: training the style ${m.style}; its swatch comes when it is added`);
            continue;
          }
          if (m.type !== 'styles') continue;
          const entry = (report.listing || []).find((a) => a.name === m.asset);
          if (entry) entry.styles = m.styles;
          showSwatches(m.asset, m.styles);
          const left = (offered.get(m.asset) || []).filter((k) => !m.styles.some((st) => st.name === k));
          offered.set(m.asset, left);
          showOffer(m.asset, left);
          report.stylesAdded = (report.stylesAdded || 0) + 1;
          setStatus(`${m.asset}: a new style, ${m.styles[m.styles.length - 1].name} (key ${m.styles.length})`);
        }
      } finally {
        report.watching = false;
        watchWriter = null;
        for (const a of offerRow.keys()) showOffer(a, []);
        try { wt.close({ closeCode: 0, reason: 'done' }); } catch (_) { /* already closed */ }
      }
    } catch (_) {
      await new Promise((r) => setTimeout(r, 2000));
    }
  }
}

// The stream on screen, once complete: whether it can switch to another style of its file
// by colour alone, and the switch (see `stream`).
let active = null;

// Open asset `name`: another style of the asset on screen by its colour alone, where the
// server and the transport allow it; else a reload with it in the fragment.
function viewAsset(name) {
  const hash = new URLSearchParams({ ...Object.fromEntries(frag), asset: name }).toString();
  if (active && active.current() === name) return;
  if (active && active.canSwitch(name)) {
    history.replaceState(null, '', '#' + hash);
    active.switchTo(name).catch((e) => {
      setStatus(`switch to ${name}: ${e.message || e}; loading it whole`);
      location.reload();
    });
    return;
  }
  location.hash = hash;
  location.reload();
}

// The cross-fade of a style switch: a frame of the old style drawn after the key, held over
// the canvas until the first frame with the new colour is drawn, then faded out over 0.3 s.
function copyToFade() {
  const cv = $('canvas'), f = $('fade');
  if (f.width !== cv.width || f.height !== cv.height) { f.width = cv.width; f.height = cv.height; }
  f.getContext('2d').drawImage(cv, 0, 0);
}
function showFade() {
  const cv = $('canvas'), f = $('fade');
  f.style.width = `${cv.clientWidth}px`; f.style.height = `${cv.clientHeight}px`;
  f.style.transition = 'none'; f.style.opacity = '1';
  report.fadeShown = (report.fadeShown || 0) + 1;
}
function fadeOut() {
  const f = $('fade');
  f.style.transition = 'opacity 0.3s linear';
  f.style.opacity = '0';
}

// Keys 1..9: the shown asset's styles, when it has several (`report.styles`, from the listing).
window.addEventListener('keydown', (e) => {
  if (e.target.tagName === 'INPUT' || !report.styles) return;
  const n = Number(e.key);
  if (Number.isInteger(n) && n >= 1 && n <= report.styles.length) viewAsset(report.styles[n - 1]);
});

// The GPU: WebGPU where the browser has it, else WebGL2 (headset browsers without WebGPU),
// the same march translated to GLSL. `cfg`: a promise of /config.json; `draw`: an asset will
// be drawn (the canvas is set up and the present pipeline compiled as well).
// `adapterReady`: a promise of the WebGPU adapter, or of null.
async function openGpu(adapterReady, cfg, draw) {
  const adapter = await adapterReady;
  if (adapter) {
    report.adapter = adapter.info ? `${adapter.info.vendor} ${adapter.info.architecture}` : 'unknown';
    // present.wgsl is fetched while the device is made
    const pw = draw ? (manifestUrl ? publishedFile('present.wgsl') : fetch('/present.wgsl')) : null;
    const device = await adapter.requestDevice({ requiredLimits: { maxTextureDimension3D: adapter.limits.maxTextureDimension3D } });
    report.marks.device = performance.now();
    device.addEventListener('uncapturederror', (e) => fail('WebGPU: ' + e.error.message));
    const gpu = { backend: 'webgpu', device };
    if (!draw) return gpu;
    const ctx = $('canvas').getContext('webgpu');
    const format = navigator.gpu.getPreferredCanvasFormat();
    ctx.configure({ device, format, alphaMode: 'opaque' });
    const res = await pw;
    if (!res.ok) throw new Error('present shader: HTTP ' + res.status);
    const wgsl = await res.text();
    // Its pipeline compiles now, long before the first frame needs it (Renderer awaits it).
    const pipeline = device.createRenderPipelineAsync(presentDescriptor(device, wgsl, format));
    pipeline.then(() => { report.marks.present = performance.now(); }, () => {});
    return Object.assign(gpu, { wg: (await cfg).workgroup, ctx, present: { wgsl, format, pipeline }, target: () => ctx.getCurrentTexture() });
  }
  // preserveDrawingBuffer: immersive mode reads this canvas (the last marched image) on
  // frames that march nothing new
  const gl = $('canvas').getContext('webgl2', { alpha: false, antialias: false, depth: false, stencil: false, preserveDrawingBuffer: true });
  if (!gl) throw new Error('this browser has neither WebGPU nor WebGL2');
  // the march writes rgba32float and r32float targets, read back exactly as WebGPU's buffers
  if (!gl.getExtension('EXT_color_buffer_float')) throw new Error('WebGL2 without EXT_color_buffer_float (float render targets)');
  const dbg = gl.getExtension('WEBGL_debug_renderer_info');
  report.adapter = dbg ? gl.getParameter(dbg.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  report.marks.device = performance.now();
  return { backend: 'webgl2', gl, target: () => gl.canvas };
}

async function main() {
  if (!token && !manifestUrl) throw new Error('no access token: open the address snerf serve printed (it ends in #token=…)');
  const want = manifestUrl ? (await readManifest()).m.asset.name : frag.get('asset');
  // What the first frame needs starts at once and goes on side by side: the config, the GPU
  // (adapter, device, the present pipeline) and, with an asset named, its session; the header
  // waits for the GPU. The listing (a session of its own, and the thumbnails' bytes) is
  // nothing that frame shows: with an asset named it starts once the frame is drawn.
  const cfg = fetchConfig();
  cfg.then(() => { report.marks.config = performance.now(); }, () => {});
  const adapterReady = navigator.gpu ? navigator.gpu.requestAdapter().catch(() => null) : Promise.resolve(null);
  const backendReady = adapterReady.then((a) => {
    report.marks.adapter = performance.now();
    return (report.backend = a ? 'webgpu' : 'webgl2');
  });
  const gpuReady = openGpu(adapterReady, cfg, !!want);
  gpuReady.catch(() => {}); // awaited below and by the stream; this only keeps an early failure from being "unhandled"
  let listing = null;
  const list = () => {
    if (!listing) {
      report.marks.listing = performance.now();
      listing = listAssets().then(showListing);
      listing.catch(() => {});
    }
    return listing;
  };
  const watch = () => { if (report.transport === 'webtransport') watchStyles(); };
  if (!want) {
    list();
    await gpuReady;
    const assets = await listing;
    watch();
    report.state = 'listed';
    setStatus(`${assets.length} asset(s); choose one`);
    return;
  }
  const [info] = await Promise.all([stream(want, backendReady, gpuReady, cfg, list), gpuReady]);
  // A listing asked for while the session was lost (the server restarting: the stream
  // resumed) is asked for once more, now that the stream is complete.
  await list().catch(() => { listing = null; return list(); });
  watch();
  report.state = 'done';
  setStatus(`${info.name}: ${info.size} bytes, SHA-256 verified; drag to orbit, wheel or pinch to zoom, WASD/QE to move`);
}

main().catch(fail);
