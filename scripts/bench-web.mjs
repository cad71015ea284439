// `snerf bench web` drives headless Chromium with this script (playwright-core), against a
// real `snerf serve` on loopback. Usage:
//   node bench-web.mjs PLAYWRIGHT_DIR FLAT_URL XR_URL FRAMES EYE_W EYE_H CAM_JSON
// FLAT_URL streams the asset into the page as a user opens it (adaptive render scale), then
// FRAMES frames are timed with the camera CAM_JSON (the frame-time size); XR_URL is the same
// asset for the immersive mode on an emulated Meta Quest 3 (iwer) at EYE_W x EYE_H per eye
// (render scale pinned at 1). Prints JSON with the page's timings (performance.now(): ms
// since navigation start).
import { launchChromium } from '../viewer/stream/tests/web/launch.mjs';
import { readFileSync } from 'fs';

const [pwDir, flatUrl, xrUrl, framesArg, eyeW, eyeH, camJson] = process.argv.slice(2);
const frames = +framesArg;
const browser = await launchChromium(pwDir);
const median = (a) => { const s = [...a].sort((x, y) => x - y); return s[s.length >> 1]; };
const out = {};
try {
  // Flat: navigation -> first frame -> complete; download rate; frame time at the camera's size.
  {
    const page = await browser.newPage();
    page.on('pageerror', (e) => console.error('page error:', e.message));
    await page.goto(flatUrl);
    await page.waitForFunction(() => window.snerf && (window.snerf.state === 'done' || window.snerf.state === 'error'), null, { timeout: 600000, polling: 20 });
    const r = await page.evaluate(() => { const s = window.snerf; return { state: s.state, error: s.error, adapter: s.adapter, firstFrameAt: s.firstFrameAt, firstFrameMs: s.firstFrameMs, firstFrame: s.firstFrame, connectedAt: s.connectedAt, downloadedAt: s.downloadedAt, completeAt: s.completeAt, completeMs: s.completeMs, bytes: s.bytes, sha256: s.sha256, marks: s.marks, crcMs: s.crcMs }; });
    if (r.state !== 'done') throw new Error('page: ' + r.error);
    const times = await page.evaluate(([n, c]) => window.snerf.benchFrames(n, JSON.parse(c)), [frames, camJson]);
    out.flat = { ...r, frameMs: median(times), frameTimes: times };
    await page.close();
  }
  // Immersive, at the headset's per-eye size.
  if (xrUrl !== '-') {
    const iwer = readFileSync(pwDir + '/node_modules/iwer/build/iwer.min.js', 'utf8');
    const page = await browser.newPage({ viewport: { width: 2 * +eyeW, height: +eyeH } });
    page.on('pageerror', (e) => console.error('page error:', e.message));
    await page.addInitScript(`${iwer}
      window.__xr = new IWER.XRDevice(IWER.metaQuest3, { stereoEnabled: true });
      window.__xr.installRuntime({ forceInstall: true });`);
    await page.goto(xrUrl);
    await page.waitForFunction(() => window.snerf.state === 'done' || window.snerf.state === 'error', null, { timeout: 600000, polling: 20 });
    await page.click('#xr', { timeout: 600000 });
    await page.waitForFunction((n) => window.snerf.xr && (window.snerf.xr.error || (window.snerf.xr.frameMs || []).length >= n), frames, { timeout: 600000, polling: 20 });
    const x = await page.evaluate(() => { const x = window.snerf.xr; return { error: x.error, firstFrameMs: x.firstFrameMs, frameMs: x.frameMs, scale: x.scale, eyes: x.eyes && x.eyes.map((e) => e.viewport) }; });
    if (x.error) throw new Error('XR: ' + x.error);
    out.xr = { ...x, frameMsMedian: median(x.frameMs) };
    await page.close();
  }
  console.log(JSON.stringify(out));
} finally {
  await browser.close();
}
