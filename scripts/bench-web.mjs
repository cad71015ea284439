// `snerf bench web` drives headless Chromium with this script (playwright-core), against a
// real `snerf serve` on loopback. One job per run, so that each measurement starts from a
// fresh browser (no shader or HTTP cache carried from the last one, as on a first visit) and
// the Rust side can interleave the jobs with the native client's runs under the same load:
//   node bench-web.mjs PLAYWRIGHT_DIR JOB_JSON
// JOB_JSON's `mode`:
//   "flat":     {url, backend, frames, cam}: the page streams the asset as a user opens it
//               (adaptive render scale); navigation -> first drawn frame -> complete view,
//               then `frames` frames timed with the camera `cam` (frame time at its size).
//   "transfer": {urls: {webtransport, https}, sha256}: the same asset streamed by the page
//               over WebTransport, then over HTTPS requests (the page's HttpSession: an init
//               script deletes `window.WebTransport` before the page's scripts run, as in a
//               browser without it). The URLs carry a tiny fixed camera so that the page's
//               frames on SwiftShader (redrawn as blocks arrive) take little of the CPU the
//               transfer needs.
//   "xr":       {url, backend, frames, eyeW, eyeH}: immersive mode on an emulated Meta
//               Quest 3 (iwer) at eyeW x eyeH per eye, render scale pinned at 1 (`xrscale=1`);
//               the march time of `frames` frames after the first (which compiles the shader).
// `backend` is "webgpu" or "webgl2" (Chromium without --enable-unsafe-webgpu: the page draws
// with WebGL2). Prints JSON with the page's timings (performance.now(): ms since navigation).
import { launchChromium } from '../viewer/stream/tests/web/launch.mjs';
import { readFileSync } from 'fs';
import { createHash } from 'crypto';

const [pwDir, jobJson] = process.argv.slice(2);
const job = JSON.parse(jobJson);
// as the Rust side reports it: the mean of the middle two of an even count
const median = (a) => { const s = [...a].sort((x, y) => x - y), n = s.length; return n % 2 ? s[n >> 1] : (s[n / 2 - 1] + s[n / 2]) / 2; };
const WAIT = { timeout: 600000, polling: 20 };

// launch.mjs reads these when the browser starts / a page opens.
if (job.backend) process.env.SNERF_NO_WEBGPU = job.backend === 'webgl2' ? '1' : '0';
// The transfer job chooses the transport per page itself.
if (job.mode === 'transfer') process.env.SNERF_NO_WEBTRANSPORT = '0';

const browser = await launchChromium(pwDir);
const out = { mode: job.mode, browserVersion: browser.version() };

async function open(url, opts = {}, init = []) {
  const page = await browser.newPage(opts);
  page.on('pageerror', (e) => console.error('page error:', e.message));
  for (const s of init) await page.addInitScript(s);
  await page.goto(url);
  await page.waitForFunction(() => window.snerf && (window.snerf.state === 'done' || window.snerf.state === 'error'), null, WAIT);
  const r = await page.evaluate(() => {
    const s = window.snerf;
    return {
      state: s.state, error: s.error, backend: s.backend, transport: s.transport, adapter: s.adapter,
      firstFrameAt: s.firstFrameAt, firstFrameMs: s.firstFrameMs, firstFrame: s.firstFrame, connectedAt: s.connectedAt,
      downloadedAt: s.downloadedAt, completeAt: s.completeAt, completeMs: s.completeMs, bytes: s.bytes, sha256: s.sha256,
      marks: s.marks, crcMs: s.crcMs, resumes: s.resumes,
    };
  });
  if (r.state !== 'done') throw new Error('page: ' + r.error);
  // The browser was asked for one renderer; a page that drew with the other measured the wrong thing.
  if (job.backend && r.backend !== job.backend) throw new Error(`asked for ${job.backend}, the page drew with ${r.backend}`);
  return { page, r };
}

try {
  if (job.mode === 'flat') {
    const { page, r } = await open(job.url);
    let times = [];
    if (job.frames > 0) times = await page.evaluate(([n, c]) => window.snerf.benchFrames(n, JSON.parse(c)), [job.frames, job.cam]);
    // Which page was measured: the server embeds app.js at build time, so a number is tied to
    // the app.js it ran (the SHA-256 of what the server served).
    const appJs = await page.evaluate(async () => (await fetch('/app.js')).text());
    out.flat = { ...r, frameMs: times.length ? median(times) : null, frameTimes: times, appJsSha256: createHash('sha256').update(appJs).digest('hex') };
    await page.close();
  } else if (job.mode === 'transfer') {
    out.transfer = {};
    for (const t of ['webtransport', 'https']) {
      const { page, r } = await open(job.urls[t], {}, t === 'https' ? ['delete window.WebTransport;'] : []);
      if (r.transport !== t) throw new Error(`asked for ${t}, the page streamed over ${r.transport}`);
      if (job.sha256 && r.sha256 !== job.sha256) throw new Error(`${t}: SHA-256 ${r.sha256}, expected ${job.sha256}`);
      out.transfer[t] = { ...r, transferMs: r.downloadedAt - r.connectedAt };
      await page.close();
    }
  } else if (job.mode === 'xr') {
    const iwer = readFileSync(pwDir + '/node_modules/iwer/build/iwer.min.js', 'utf8');
    const { page, r } = await open(job.url, { viewport: { width: 2 * job.eyeW, height: job.eyeH } }, [`${iwer}
      window.__xr = new IWER.XRDevice(IWER.metaQuest3, { stereoEnabled: true });
      window.__xr.installRuntime({ forceInstall: true });`]);
    await page.click('#xr', { timeout: 600000 });
    // The first march also compiles the pipeline at its first dispatch (tens of seconds on
    // SwiftShader at this size): it is reported apart, and `frames` more are timed after it.
    await page.waitForFunction((n) => window.snerf.xr && (window.snerf.xr.error || (window.snerf.xr.frameMs || []).length >= n), job.frames + 1, WAIT);
    const x = await page.evaluate(() => { const x = window.snerf.xr; return { error: x.error, firstFrameMs: x.firstFrameMs, frameMs: x.frameMs, scale: x.scale, eyes: x.eyes && x.eyes.map((e) => e.viewport) }; });
    if (x.error) throw new Error('XR: ' + x.error);
    const steady = x.frameMs.slice(1);
    out.xr = { ...x, backend: r.backend, adapter: r.adapter, transport: r.transport, firstMarchMs: x.frameMs[0], steadyMs: steady, frameMsMedian: median(steady) };
    await page.close();
  } else {
    throw new Error('unknown mode ' + job.mode);
  }
  console.log(JSON.stringify(out));
} finally {
  await browser.close();
}
