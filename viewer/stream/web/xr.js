// snerf web viewer, immersive mode: an `immersive-vr` WebXR session that draws each eye with
// that XR view's own projection and pose. The march is the same WebGPU compute pass as the
// flat page (shaders/march.wgsl, composed by the server); both eyes are marched in one
// submission and presented side by side (shaders/present.wgsl) into an OffscreenCanvas, which
// is drawn into the XR layer's framebuffer with WebGL2 (WebXR layers are WebGL).
//
// Placement (derived from the asset, see `placement`): an object floats at arm's length in
// front of the user, its radius ~25 cm; a room or unbounded scene puts its floor (the asset's
// `floor`, else the orbit's lowest camera height) at the floor, the user standing where the
// capture's start view stood, scaled so that view's height is a standing eye height (1.6 m).
//
// Controllers (documented in web/README.md): left thumbstick walks (1.5 m/s along where the
// head looks, on the floor plane), right thumbstick snaps the turn by 30°, grip with one hand
// drags the scene, with both hands scales it about their midpoint, trigger (select; a pinch
// with hands) plays or pauses a 4D asset. The head pose goes to the server as datagrams so
// blocks come in the order the user will look; the frame loop never waits on the network.

const WALK = 1.5; // m/s
const SNAP = Math.PI / 6;
const EYE_HEIGHT = 1.6; // m
const OBJECT_RADIUS = 0.25; // m
const OBJECT_AT = [0, 1.3, -0.6]; // m, in local-floor space

const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scl = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
const unit = (a) => scl(a, 1 / Math.hypot(a[0], a[1], a[2]));
// 3x3 as columns [c0, c1, c2].
const mulv = (m, v) => add(add(scl(m[0], v[0]), scl(m[1], v[1])), scl(m[2], v[2]));
const ry = (a, v) => [Math.cos(a) * v[0] + Math.sin(a) * v[2], v[1], -Math.sin(a) * v[0] + Math.cos(a) * v[2]];

export async function xrSupported() {
  try {
    return !!navigator.xr && (await navigator.xr.isSessionSupported('immersive-vr'));
  } catch {
    return false;
  }
}

// Where local-floor space sits in the world: world = origin + k * B * (Ry(yaw) * ref + p),
// B's columns the world directions of ref x (right), y (up), z (back).
export function placement(h, orbit) {
  const up = unit(orbit.up);
  let fwd = sub(orbit.start, scl(up, dot(orbit.start, up)));
  fwd = Math.hypot(...fwd) < 1e-6 ? unit(cross(up, [1, 0, 0])) : scl(unit(fwd), -1); // start -> centre
  const right = unit(cross(fwd, up));
  const B = [right, up, scl(fwd, -1)];
  if (h.kind === 'object') {
    const k = 1 / h.space.scale / OBJECT_RADIUS;
    return { B, k, origin: sub(orbit.center, scl(mulv(B, OBJECT_AT), k)) };
  }
  // Standing where the start view stood, feet on the floor.
  const startEye = add(orbit.center, scl(add(scl(scl(fwd, -1), Math.cos(orbit.elevation)), scl(up, Math.sin(orbit.elevation))), orbit.radius));
  const floorH = h.floor != null ? h.floor : dot(orbit.center, up) - orbit.radius;
  const eyeH = dot(startEye, up) - floorH;
  const k = (eyeH > 1e-6 ? eyeH : orbit.radius / 3) / EYE_HEIGHT;
  const origin = add(sub(startEye, scl(up, dot(startEye, up))), scl(up, floorH));
  return { B, k, origin };
}

// The eye camera in world space ({c2w rows, fx, fy, cx, cy, width, height}) of an XR view
// (column-major projection and ref-space transform) for a w x h image.
export function eyeCamera(P, T, w, hh, place, rig) {
  const fx = (P[0] * w) / 2, fy = (P[5] * hh) / 2;
  const cx = (w / 2) * (1 - P[8]), cy = (hh / 2) * (1 + P[9]);
  const toWorldDir = (d) => mulv(place.B, ry(rig.yaw, d));
  const cols = [0, 1, 2].map((c) => toWorldDir([T[4 * c], T[4 * c + 1], T[4 * c + 2]]));
  const eye = add(place.origin, scl(mulv(place.B, add(ry(rig.yaw, [T[12], T[13], T[14]]), rig.p)), place.k));
  const c2w = [0, 1, 2].map((i) => [cols[0][i], cols[1][i], cols[2][i], eye[i]]);
  return { c2w, fx, fy, cx, cy, width: w, height: hh };
}

// Reprojection of the last marched image of an eye to the eye's current pose (rotational
// timewarp): the homography taking a fragment of the eye's viewport at the current pose
// (gl_FragCoord minus the viewport origin: pixel edges, y up) to homogeneous pixel
// coordinates (pixel edges, y down) in the image marched at camera `old`. `cur` is the eye's
// camera now, at the viewport's size; both are `eyeCamera` cameras (c2w rows, the camera
// looks down -z, y up, pixel (x, y)'s ray ((x+0.5-cx)/fx, -(y+0.5-cy)/fy, -1), as
// shaders/march.wgsl `render_at`). Directions only, so the eye's translation since the march
// is not compensated (see web/README.md, "Immersive mode"). The third coordinate is the
// depth along the old camera's view axis: <= 0 for a ray behind it. Returns a column-major
// 3x3 for uniformMatrix3fv.
export function reprojection(cur, old) {
  // fragment -> ray in the current camera
  const K1 = [[1 / cur.fx, 0, -cur.cx / cur.fx], [0, 1 / cur.fy, (cur.cy - cur.height) / cur.fy], [0, 0, -1]];
  // current camera -> world -> old camera: Ro^T Rn
  const R = [0, 1, 2].map((i) => [0, 1, 2].map((j) => [0, 1, 2].reduce((a, k) => a + old.c2w[k][i] * cur.c2w[k][j], 0)));
  // ray in the old camera -> its pixel (x + 0.5, y + 0.5) times the depth -z
  const K2 = [[old.fx, 0, -old.cx], [0, -old.fy, -old.cy], [0, 0, -1]];
  const mm = (A, B) => A.map((r) => [0, 1, 2].map((j) => r[0] * B[0][j] + r[1] * B[1][j] + r[2] * B[2][j]));
  const M = mm(K2, mm(R, K1));
  return [M[0][0], M[1][0], M[2][0], M[0][1], M[1][1], M[2][1], M[0][2], M[1][2], M[2][2]];
}

const VS = `#version 300 es
void main() {
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}`;
// One eye: `warp` (see `reprojection`) maps the fragment to the last image's pixel; `size` is
// that eye's image size in pixels and `rect` turns its pixel into texture coordinates (origin
// of its rectangle, one pixel), the offscreen image uploaded with UNPACK_FLIP_Y (GL's y up).
// Outside the image the nearest edge pixel (clamp) is shown: see web/README.md.
const FS = `#version 300 es
precision highp float; uniform sampler2D img; uniform mat3 warp; uniform vec2 origin, size; uniform vec4 rect;
out vec4 o;
void main() {
  vec3 q = warp * vec3(gl_FragCoord.xy - origin, 1.0);
  if (q.z <= 0.0) { o = vec4(0.12, 0.12, 0.12, 1.0); return; } // behind the old camera
  vec2 p = clamp(q.xy / q.z, vec2(0.5), size - 0.5);
  o = vec4(texture(img, rect.xy + p * rect.zw).rgb, 1.0);
}`;

function program(gl) {
  const sh = (type, src) => {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error('XR blit shader: ' + gl.getShaderInfoLog(s));
    return s;
  };
  const p = gl.createProgram();
  gl.attachShader(p, sh(gl.VERTEX_SHADER, VS));
  gl.attachShader(p, sh(gl.FRAGMENT_SHADER, FS));
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error('XR blit program: ' + gl.getProgramInfoLog(p));
  return p;
}

// Start the session. `api`: what the streaming page shares (see app.js `stream`); `report`:
// window.snerf, where the session's state goes (`report.xr`).
export async function enterXR(api, report) {
  const t0 = performance.now();
  const xr = (report.xr = { state: 'starting', firstFrameMs: null, frames: 0, scale: 1, eyes: null, rig: null, error: null });
  const glCanvas = document.createElement('canvas');
  const gl = glCanvas.getContext('webgl2', { xrCompatible: true, alpha: false, antialias: false, depth: false });
  if (!gl) throw new Error('no WebGL2 for the XR layer');
  const session = await navigator.xr.requestSession('immersive-vr', { requiredFeatures: ['local-floor'], optionalFeatures: ['hand-tracking'] });
  const layer = new XRWebGLLayer(session, gl, { antialias: false, depth: false, alpha: false });
  session.updateRenderState({ baseLayer: layer });
  if ('fixedFoveation' in layer) layer.fixedFoveation = 0.5;
  // The display's highest refresh rate up to 90 Hz (120 where that is all it offers): the
  // render scale then adapts to hold it.
  const rates = session.supportedFrameRates ? Array.from(session.supportedFrameRates) : [];
  if (rates.length && session.updateTargetFrameRate) {
    const want = rates.filter((r) => r <= 90).sort((a, b) => b - a)[0] ?? Math.min(...rates);
    await session.updateTargetFrameRate(want).catch(() => {});
  }
  const ref = await session.requestReferenceSpace('local-floor');
  const place = placement(api.header(), api.orbit());
  const rig = { p: [0, 0, 0], yaw: 0 };
  xr.place = place;
  xr.rig = rig;
  const prog = program(gl);
  const tex = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, tex);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
  const loc = Object.fromEntries(['warp', 'origin', 'size', 'rect'].map((n) => [n, gl.getUniformLocation(prog, n)]));
  // WebGPU marches into an OffscreenCanvas of its own; the WebGL2 renderer (app.js
  // `RendererGL`) into its context's canvas, which is uploaded the same way.
  const off = api.gpu.backend === 'webgl2' ? api.gpu.gl.canvas : new OffscreenCanvas(16, 16);
  const ctx = api.gpu.backend === 'webgl2' ? null : off.getContext('webgpu');
  if (ctx) ctx.configure({ device: api.gpu.device, format: 'rgba8unorm', alphaMode: 'opaque' });
  // Dynamic render scale: the fraction of each eye's pixels marched, held to the display's
  // refresh (session.frameRate where the browser says it, else 72 Hz).
  let scale = api.capture ? 1 : api.fixedScale ?? 0.5;
  let busy = false, last = null, lastPose = 0, grab = null;
  // What `tex` holds: the last marched image, its size and each eye's rectangle and camera
  // (every presented frame is reprojected from it to the eyes' current poses).
  let shown = null;
  const pressed = new Map();
  session.addEventListener('select', () => api.togglePlay());
  session.addEventListener('end', () => { api.setXR(false); xr.state = 'ended'; });
  api.setXR(true);

  function edge(key, on) {
    const was = pressed.get(key) || false;
    pressed.set(key, on);
    return on && !was;
  }
  // Controllers: thumbsticks, grip drag / two-hand scale (see the top of this file).
  function input(frame, dt, head) {
    const grips = [];
    for (const src of session.inputSources) {
      const gp = src.gamepad;
      if (!gp) continue;
      const ax = gp.axes.length >= 4 ? [gp.axes[2], gp.axes[3]] : [gp.axes[0] || 0, gp.axes[1] || 0];
      if (src.handedness === 'left' && Math.hypot(ax[0], ax[1]) > 0.15) {
        // Walk on the floor plane along the head's heading (stick up = -y = forward).
        const f = ry(rig.yaw, head.fwd), fl = Math.hypot(f[0], f[2]) || 1;
        const fw = [f[0] / fl, 0, f[2] / fl], rt = [-fw[2], 0, fw[0]];
        rig.p = add(rig.p, scl(add(scl(fw, -ax[1]), scl(rt, ax[0])), WALK * dt));
      }
      if (src.handedness === 'right') {
        const dir = ax[0] > 0.7 ? -1 : ax[0] < -0.7 ? 1 : 0;
        if (edge('snap', dir !== 0) && dir !== 0) {
          // Turn about the head, not the rig's origin: the head stays where it is.
          const before = add(ry(rig.yaw, head.pos), rig.p);
          rig.yaw += dir * SNAP;
          rig.p = sub(before, ry(rig.yaw, head.pos));
        }
      }
      const grip = gp.buttons[1] && gp.buttons[1].pressed;
      const gpose = grip && src.gripSpace && frame.getPose(src.gripSpace, ref);
      if (gpose) {
        const q = gpose.transform.position;
        grips.push(add(ry(rig.yaw, [q.x, q.y, q.z]), rig.p));
      }
    }
    if (grips.length === 1 && grab && grab.n === 1) {
      // The scene follows the hand: move the rig the other way.
      rig.p = sub(rig.p, sub(grips[0], grab.at[0]));
      grips[0] = grab.at[0];
    } else if (grips.length === 2 && grab && grab.n === 2) {
      const d0 = Math.hypot(...sub(grab.at[0], grab.at[1])), d1 = Math.hypot(...sub(grips[0], grips[1]));
      if (d0 > 1e-3 && d1 > 1e-3) {
        // Hands apart = the scene grows: fewer world units per metre, about the midpoint.
        const m = scl(add(grips[0], grips[1]), 0.5);
        const k1 = (place.k * d0) / d1;
        place.origin = add(place.origin, scl(mulv(place.B, m), place.k - k1));
        place.k = k1;
      }
    }
    grab = grips.length ? { n: grips.length, at: grips } : null;
  }

  function onFrame(t, frame) {
    session.requestAnimationFrame(onFrame);
    const dt = last === null ? 0 : Math.min(0.1, (t - last) / 1000);
    const frameMs = last === null ? null : t - last;
    last = t;
    const pose = frame.getViewerPose(ref);
    if (!pose) return;
    const T = pose.transform.matrix;
    const head = { pos: [T[12], T[13], T[14]], fwd: [-T[8], -T[9], -T[10]] };
    input(frame, dt, head);
    api.advance(dt);
    // Head pose to the server (at most every 50 ms; never awaited).
    if (t - lastPose > 50) {
      lastPose = t;
      const c = eyeCamera(pose.views[0].projectionMatrix, T, 2, 2, place, rig);
      const P = pose.views[0].projectionMatrix;
      const fov = (2 * Math.atan(Math.max(1 / P[0], 1 / P[5])) * 180) / Math.PI;
      api.sendPose([c.c2w[0][3], c.c2w[1][3], c.c2w[2][3]], [-c.c2w[0][2], -c.c2w[1][2], -c.c2w[2][2]], fov);
    }
    const r = api.renderer();
    gl.bindFramebuffer(gl.FRAMEBUFFER, layer.framebuffer);
    if (!r || !api.ready()) {
      // Not renderable yet: a dim grey, never a black eye.
      gl.clearColor(0.12, 0.12, 0.12, 1);
      gl.clear(gl.COLOR_BUFFER_BIT);
      return;
    }
    const fbW = layer.framebufferWidth, fbH = layer.framebufferHeight;
    const eyes = pose.views.map((v) => {
      const vp = layer.getViewport(v);
      return { v, vp, w: Math.max(8, Math.round(vp.width * scale)), h: Math.max(8, Math.round(vp.height * scale)) };
    }).filter((e) => e.vp.width > 0);
    const W = Math.max(8, Math.round(fbW * scale)), H = Math.max(8, Math.round(fbH * scale));
    if (off.width !== W || off.height !== H) { off.width = W; off.height = H; }
    const views = eyes.map((e) => {
      const x = Math.min(W - e.w, Math.round(e.vp.x * scale));
      const y = Math.max(0, H - Math.round((e.vp.y + e.vp.height) * scale));
      e.x = x; e.y = y;
      e.cam = eyeCamera(e.v.projectionMatrix, e.v.transform.matrix, e.w, e.h, place, rig);
      // the silhouette pass is chosen at the eye's own pixels, not the adaptive scale's
      e.cam.lodFx = e.cam.fx * e.vp.width / e.w;
      return { cam: e.cam, x, y };
    });
    const time = api.time();
    // Present: each eye's last marched image, reprojected to the eye's current pose (the
    // current pose: the camera at the viewport's own size, whatever the render scale).
    const present = () => {
      gl.bindFramebuffer(gl.FRAMEBUFFER, layer.framebuffer);
      gl.bindTexture(gl.TEXTURE_2D, tex);
      gl.useProgram(prog);
      eyes.forEach((e, i) => {
        const s = shown.eyes[i];
        if (!s) return;
        const cur = eyeCamera(e.v.projectionMatrix, e.v.transform.matrix, e.vp.width, e.vp.height, place, rig);
        gl.viewport(e.vp.x, e.vp.y, e.vp.width, e.vp.height);
        gl.uniformMatrix3fv(loc.warp, false, reprojection(cur, s.cam));
        gl.uniform2f(loc.origin, e.vp.x, e.vp.y);
        gl.uniform2f(loc.size, s.w, s.h);
        gl.uniform4f(loc.rect, s.x / shown.W, (shown.H - s.y) / shown.H, 1 / shown.W, -1 / shown.H);
        gl.drawArrays(gl.TRIANGLES, 0, 3);
        e.cur = cur;
      });
      if (api.capture) {
        // What the layer shows this frame, per eye, with the camera it was reprojected to.
        xr.shown = {
          n: (xr.shown ? xr.shown.n : 0) + 1,
          marches: xr.frames,
          eyes: eyes.map((e) => {
            const px = new Uint8Array(e.vp.width * e.vp.height * 4);
            gl.readPixels(e.vp.x, e.vp.y, e.vp.width, e.vp.height, gl.RGBA, gl.UNSIGNED_BYTE, px);
            return { cam: e.cur, viewport: [e.vp.x, e.vp.y, e.vp.width, e.vp.height], gl: px };
          }),
        };
      }
    };
    // While a march is in flight (or, with `xrhold`, for tests, once one has completed) the
    // last image is presented at the new pose: the loop never waits.
    if (busy || (api.hold && xr.frames > 0)) { if (shown) present(); return; }
    busy = true;
    const ts = performance.now();
    const done = r.render(views, time, ctx ? ctx.getCurrentTexture() : off, api.capture);
    // The image being marched becomes what is shown (the upload waits for the march on the GPU).
    gl.bindTexture(gl.TEXTURE_2D, tex);
    gl.pixelStorei(gl.UNPACK_FLIP_Y_WEBGL, true);
    gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA, gl.RGBA, gl.UNSIGNED_BYTE, off);
    shown = { W, H, eyes: eyes.map((e) => ({ cam: e.cam, x: e.x, y: e.y, w: e.w, h: e.h })) };
    present();
    // What the layer shows, per eye, to compare with the marched image.
    const glShot = api.capture ? xr.shown.eyes.map((e) => e.gl) : null;
    done.then((out) => {
      const ms = performance.now() - ts;
      busy = false;
      xr.frames++;
      if (xr.firstFrameMs === null) { xr.firstFrameMs = performance.now() - t0; xr.state = 'running'; }
      const target = 1000 / (session.frameRate || 72);
      xr.frameMs = (xr.frameMs || []).concat([ms]).slice(-64);
      if (!api.capture && api.fixedScale == null) {
        const k = Math.sqrt((0.9 * target) / Math.max(ms, frameMs || ms, 0.1));
        if (k < 0.95 || (k > 1.1 && scale < 1)) scale = Math.min(1, Math.max(0.1, scale * Math.min(1.25, Math.max(0.6, k))));
      }
      xr.scale = scale;
      xr.ms = ms;
      xr.eyes = eyes.map((e, i) => ({
        cam: e.cam,
        projection: Array.from(e.v.projectionMatrix),
        transform: Array.from(e.v.transform.matrix),
        viewport: [e.vp.x, e.vp.y, e.vp.width, e.vp.height],
        rgba: out ? out[i] : null,
        gl: glShot ? glShot[i] : null,
      }));
      xr.time = time;
    }, (e) => { busy = false; xr.error = String(e.message || e); });
  }
  session.requestAnimationFrame(onFrame);
  xr.state = 'started';
  return session;
}
