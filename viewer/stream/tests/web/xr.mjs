// Drives the web viewer's immersive mode in headless Chromium on an emulated Meta Quest 3
// (npm iwer, installed over Chromium's own navigator.xr) for tests/web.rs. No mocks: the real
// page from the real server, the real WebGPU march, the real WebXR session API as iwer
// emulates it. Usage: node xr.mjs PLAYWRIGHT_DIR URL [WIDTH HEIGHT [early]]
// Prints JSON: {before, moved, turned, walked, snapped, gripped, page}, each a snapshot of
// window.snerf.xr (eyes with cameras, raw XR matrices, marched pixels and what the WebGL
// layer shows). With `early`: enters VR while the asset still streams, turns the head
// around a moment later, waits for the stream to end and prints {turnedAt, posesSent}.
// With `hold YAW PITCH` (a page with `xrhold=1`: one march, then none): waits for the first
// march, turns the head by YAW then PITCH degrees, lets frames present and prints
// {before, held}: the march's snapshot and the last presented frame (xr.shown: per eye the
// camera it was reprojected to and the layer's pixels).
import { launchChromium } from './launch.mjs';
import { readFileSync } from 'fs';

const [pwDir, url, width, height, mode, ...modeArgs] = process.argv.slice(2);
const iwer = readFileSync(pwDir + '/node_modules/iwer/build/iwer.min.js', 'utf8');

const browser = await launchChromium(pwDir);
const log = (...a) => console.error(...a);
try {
  // iwer sizes the XR framebuffer to the window: WIDTH x HEIGHT, two eyes side by side.
  const page = await browser.newPage({ viewport: { width: +(width || 192), height: +(height || 96) } });
  page.on('console', (m) => log('page:', m.text()));
  page.on('pageerror', (e) => log('page error:', e.message));
  await page.addInitScript(`${iwer}
    window.__xr = new IWER.XRDevice(IWER.metaQuest3, { stereoEnabled: true });
    window.__xr.installRuntime({ forceInstall: true });`);
  await page.goto(url);
  const wait = (fn, arg) => page.waitForFunction(fn, arg, { timeout: 240000, polling: 50 });
  if (mode === 'early') {
    await wait(() => window.snerf.state === 'error' || !document.getElementById('xr').hidden);
    await page.click('#xr');
    log('entered VR while streaming');
    await wait(() => (window.snerf.posesSent || 0) >= 2 || window.snerf.state === 'error');
    log('poses sent');
    // Turn around (180 degrees about +y).
    await page.evaluate(() => window.__xr.quaternion.set(0, 1, 0, 0));
    const turnedAt = await page.evaluate(() => ({ blocks: window.snerf.blocks, posesSent: window.snerf.posesSent }));
    await wait(() => window.snerf.state === 'done' || window.snerf.state === 'error');
    const end = await page.evaluate(() => ({ state: window.snerf.state, error: window.snerf.error, blocks: window.snerf.blocks, posesSent: window.snerf.posesSent, lastPose: window.snerf.lastPose, xr: window.snerf.xr && { error: window.snerf.xr.error, place: window.snerf.xr.place } }));
    console.log(JSON.stringify({ turnedAt, end }));
    // (process.exit skips `finally`: a browser not closed leaves its /tmp/org.chromium.* behind)
    await browser.close();
    process.exit(0);
  }
  await wait(() => window.snerf && (window.snerf.state === 'done' || window.snerf.state === 'error'));
  if (mode === 'hold') {
    if ((await page.evaluate(() => window.snerf.state)) !== 'done') throw new Error('page: ' + (await page.evaluate(() => window.snerf.error)));
    await wait(() => !document.getElementById('xr').hidden);
    await page.click('#xr');
    await wait(() => window.snerf.xr && (window.snerf.xr.error || (window.snerf.xr.frames >= 1 && window.snerf.xr.eyes && window.snerf.xr.shown)));
    const before = await page.evaluate(() => {
      const x = window.snerf.xr;
      return { error: x.error, frames: x.frames, time: x.time, scale: x.scale, place: x.place, eyes: x.eyes.map((e) => ({ cam: e.cam, projection: e.projection, transform: e.transform, viewport: e.viewport, rgba: Array.from(e.rgba), gl: Array.from(e.gl) })) };
    });
    const n0 = await page.evaluate(() => window.snerf.xr.shown.n);
    // Head turned YAW degrees left (about +y), then PITCH up (about its own x).
    const [yaw, pitch] = modeArgs.map((a) => (+a * Math.PI) / 360);
    await page.evaluate(([y, p]) => window.__xr.quaternion.set(Math.cos(y) * Math.sin(p), Math.sin(y) * Math.cos(p), -Math.sin(y) * Math.sin(p), Math.cos(y) * Math.cos(p)), [yaw, pitch]);
    // A few frames at the new pose (iwer applies it from the next frame on).
    await wait((n) => window.snerf.xr.shown.n >= n + 4, n0);
    const held = await page.evaluate(() => {
      const s = window.snerf.xr.shown;
      return { backend: window.snerf.backend, n: s.n, marches: s.marches, marchesNow: window.snerf.xr.frames, eyes: s.eyes.map((e) => ({ cam: e.cam, viewport: e.viewport, gl: Array.from(e.gl) })) };
    });
    console.log(JSON.stringify({ before, held }));
    await browser.close();
    process.exit(0);
  }
  const state = await page.evaluate(() => window.snerf.state);
  if (state !== 'done') throw new Error('page: ' + (await page.evaluate(() => window.snerf.error)));
  await wait(() => !document.getElementById('xr').hidden);
  await page.click('#xr');
  const frames = async (n) => {
    const f0 = await page.evaluate(() => (window.snerf.xr ? window.snerf.xr.frames : 0));
    await wait((m) => window.snerf.xr && (window.snerf.xr.error || (window.snerf.xr.frames >= m && window.snerf.xr.eyes)), f0 + n);
  };
  const snap = () => page.evaluate(() => {
    const x = window.snerf.xr;
    if (x.error) return { error: x.error };
    return {
      error: null, frames: x.frames, firstFrameMs: x.firstFrameMs, scale: x.scale, time: x.time,
      place: x.place, rig: JSON.parse(JSON.stringify(x.rig)), posesSent: window.snerf.posesSent || 0,
      head: [window.__xr.position.x, window.__xr.position.y, window.__xr.position.z],
      eyes: x.eyes.map((e) => ({ cam: e.cam, projection: e.projection, transform: e.transform, viewport: e.viewport, rgba: Array.from(e.rgba), gl: Array.from(e.gl) })),
    };
  });
  await frames(2);
  const before = await snap();
  // Move the head 30 cm right and 20 cm back.
  await page.evaluate(() => window.__xr.position.set(0.3, 1.6, 0.2));
  await frames(2);
  const moved = await snap();
  // Turn the head 90 degrees left (about +y).
  await page.evaluate(() => window.__xr.quaternion.set(0, Math.SQRT1_2, 0, Math.SQRT1_2));
  await frames(3);
  const turned = await snap();
  // Left thumbstick fully forward for about half a second, then released.
  await page.evaluate(() => window.__xr.controllers.left.updateAxes('thumbstick', 0, -1));
  const t0 = Date.now();
  await frames(3);
  while (Date.now() - t0 < 500) await frames(1);
  await page.evaluate(() => window.__xr.controllers.left.updateAxes('thumbstick', 0, 0));
  await frames(2);
  const walked = await snap();
  // Right thumbstick to the right: one snap turn (30 degrees clockwise), however long held.
  await page.evaluate(() => window.__xr.controllers.right.updateAxes('thumbstick', 1, 0));
  await frames(4);
  await page.evaluate(() => window.__xr.controllers.right.updateAxes('thumbstick', 0, 0));
  await frames(2);
  const snapped = await snap();
  // Grip (squeeze, right) held while the controller moves 20 cm up: the scene follows the hand.
  await page.evaluate(() => window.__xr.controllers.right.updateButtonValue('squeeze', 1));
  await frames(2);
  await page.evaluate(() => { const p = window.__xr.controllers.right.position; p.set(p.x, p.y + 0.2, p.z); });
  await frames(3);
  await page.evaluate(() => window.__xr.controllers.right.updateButtonValue('squeeze', 0));
  await frames(2);
  const gripped = await snap();
  console.log(JSON.stringify({ before, moved, turned, walked, snapped, gripped, page: { error: await page.evaluate(() => window.snerf.error), backend: await page.evaluate(() => window.snerf.backend) } }));
} finally {
  await browser.close();
}
