// Renders an exported KHR_gaussian_splatting .glb with Babylon.js (the npm packages babylonjs
// + babylonjs-loaders, the engine's own glTF loader and splat renderer) in headless Chromium
// (WebGL2 on SwiftShader), with the camera placed exactly at a `snerf render` pose, and writes
// the frame as PNG. For tests/splats_engine.rs and `BENCH.md` §6b.
//
// Usage: node babylon_render.mjs PLAYWRIGHT_DIR BABYLON_DIR SCENE.glb POSES.json OUT_PREFIX
// POSES.json: { "width", "height", "fov_y" (degrees), "background": [r,g,b],
//               "poses": [ c2w rows [[r00,r01,r02,tx],[r10,..,ty],[r20,..,tz]], ... ] }
// Writes OUT_PREFIX<i>.png per pose and prints {"load_ms", "frames": [...], "splats"} as JSON.
//
// The scene is right-handed (scene.useRightHandedSystem), so the glTF loader adds no
// handedness flip and glTF world coordinates are the asset's world coordinates. The camera's
// view matrix is the inverse of the pose (OpenGL convention: x right, y up, looking down −z)
// and its projection Babylon's right-handed perspective with the pose's vertical field of view.
// The glb and the engine's scripts are served to the page by request interception (no network).
import { readFileSync, writeFileSync } from 'node:fs';
import { pathToFileURL } from 'node:url';
import path from 'node:path';

const [pwDir, babylonDir, glbPath, posesPath, outPrefix] = process.argv.slice(2);
const here = path.dirname(new URL(import.meta.url).pathname);
const { launchChromium } = await import(pathToFileURL(path.join(here, '../../viewer/stream/tests/web/launch.mjs')).href);
const spec = JSON.parse(readFileSync(posesPath, 'utf8'));
const ORIGIN = 'http://snerf.invalid/';
const files = {
  'babylon.js': [path.join(babylonDir, 'node_modules/babylonjs/babylon.js'), 'text/javascript'],
  'loaders.js': [path.join(babylonDir, 'node_modules/babylonjs-loaders/babylonjs.loaders.min.js'), 'text/javascript'],
  'scene.glb': [glbPath, 'model/gltf-binary'],
};
const html = `<!doctype html><html><body style="margin:0">
<canvas id="c" width="${spec.width}" height="${spec.height}" style="width:${spec.width}px;height:${spec.height}px"></canvas>
<script src="${ORIGIN}babylon.js"></script><script src="${ORIGIN}loaders.js"></script></body></html>`;

process.env.SNERF_NO_WEBGPU = '1';
const browser = await launchChromium(pwDir);
let code = 0;
try {
  const page = await browser.newPage({ viewport: { width: spec.width, height: spec.height }, deviceScaleFactor: 1 });
  page.on('pageerror', (e) => console.error('page error:', e.message));
  page.on('console', (m) => { if (m.type() === 'error') console.error('page:', m.text()); });
  await page.route(ORIGIN + '**', (route) => {
    const name = route.request().url().slice(ORIGIN.length);
    if (name === '' || name === 'index.html') return route.fulfill({ body: html, contentType: 'text/html' });
    const f = files[name];
    if (!f) return route.fulfill({ status: 404, body: 'not found' });
    return route.fulfill({ body: readFileSync(f[0]), contentType: f[1] });
  });
  await page.goto(ORIGIN + 'index.html');
  const result = await page.evaluate(async (spec) => {
    const canvas = document.getElementById('c');
    const engine = new BABYLON.Engine(canvas, false, { preserveDrawingBuffer: true, antialias: false, disableWebGL2Support: false });
    engine.setHardwareScalingLevel(1);
    const scene = new BABYLON.Scene(engine);
    scene.useRightHandedSystem = true;
    const bg = spec.background;
    scene.clearColor = new BABYLON.Color4(bg[0], bg[1], bg[2], 1);
    // A camera whose view matrix is the pose's inverse, exactly.
    class PoseCamera extends BABYLON.Camera {
      _getViewMatrix() { return this._pose; }
    }
    const cam = new PoseCamera('pose', BABYLON.Vector3.Zero(), scene);
    cam.fov = spec.fov_y * Math.PI / 180;
    cam.fovMode = BABYLON.Camera.FOVMODE_VERTICAL_FIXED;
    cam.minZ = 0.001;
    cam.maxZ = 1e4;
    scene.activeCamera = cam;
    const setPose = (c2w) => {
      // view = [Rᵀ | −Rᵀt]; Babylon's array is column-major for column vectors (m[12..14] = translation)
      const R = (r, c) => c2w[r][c];
      const t = [c2w[0][3], c2w[1][3], c2w[2][3]];
      const m = new Array(16).fill(0);
      for (let r = 0; r < 3; r++) {
        for (let c = 0; c < 3; c++) m[c * 4 + r] = R(c, r);
        m[12 + r] = -(R(0, r) * t[0] + R(1, r) * t[1] + R(2, r) * t[2]);
      }
      m[15] = 1;
      cam._pose = BABYLON.Matrix.FromArray(m);
      cam.position = new BABYLON.Vector3(t[0], t[1], t[2]);
      cam.getViewMatrix(true);
      cam.computeWorldMatrix(true);
    };
    setPose(spec.poses[0]);
    const t0 = performance.now();
    const res = await BABYLON.SceneLoader.ImportMeshAsync('', 'http://snerf.invalid/', 'scene.glb', scene);
    const splat = res.meshes.find((m) => m instanceof BABYLON.GaussianSplattingMesh);
    if (!splat) throw new Error('no GaussianSplattingMesh in the loaded scene: ' + res.meshes.map((m) => m.getClassName()).join(','));
    await scene.whenReadyAsync();
    const loadMs = performance.now() - t0;
    const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
    const frames = [];
    for (const c2w of spec.poses) {
      setPose(c2w);
      // The splats are depth-sorted in a worker: render until two frames a while apart agree.
      let last = null, shot = null;
      for (let k = 0; k < 80; k++) {
        scene.render();
        await sleep(150);
        scene.render();
        shot = canvas.toDataURL('image/png');
        if (k >= 3 && shot === last) break;
        last = shot;
      }
      frames.push(shot);
    }
    return { loadMs, frames, splats: splat.splatCount ?? null };
  }, spec);
  const out = [];
  result.frames.forEach((d, i) => {
    const f = `${outPrefix}${i}.png`;
    writeFileSync(f, Buffer.from(d.split(',')[1], 'base64'));
    out.push(f);
  });
  console.log(JSON.stringify({ load_ms: result.loadMs, frames: out, splats: result.splats }));
} catch (e) {
  console.error(String(e && e.stack ? e.stack : e));
  code = 1;
} finally {
  await browser.close();
}
process.exit(code);
