// Drives the web viewer's immersive mode in headless Chromium on an emulated Meta Quest 3
// (npm iwer, installed over Chromium's own navigator.xr) for tests/web.rs. No mocks: the real
// page from the real server, the real WebGPU march, the real WebXR session API as iwer
// emulates it. Usage: node xr.mjs PLAYWRIGHT_DIR URL [WIDTH HEIGHT]
// Prints JSON: {before, moved, turned, walked, page}, each a snapshot of window.snerf.xr
// (eyes with cameras, raw XR matrices, marched pixels and what the WebGL layer shows).
import { createRequire } from 'module';
import { readFileSync } from 'fs';

const [pwDir, url, width, height] = process.argv.slice(2);
const require = createRequire(pwDir + '/');
const { chromium } = require('playwright-core');
const iwer = readFileSync(pwDir + '/node_modules/iwer/build/iwer.min.js', 'utf8');

const browser = await chromium.launch({
  executablePath: process.env.SNERF_CHROMIUM || '/usr/bin/chromium',
  headless: true,
  args: ['--no-sandbox', '--disable-background-networking', '--disable-component-update', '--no-first-run',
    '--enable-unsafe-webgpu', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist', '--enable-gpu',
    '--enable-features=Vulkan', '--use-vulkan=swiftshader', '--use-angle=swiftshader'],
});
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
  await wait(() => window.snerf && (window.snerf.state === 'done' || window.snerf.state === 'error'));
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
  console.log(JSON.stringify({ before, moved, turned, walked, page: { error: await page.evaluate(() => window.snerf.error) } }));
} finally {
  await browser.close();
}
