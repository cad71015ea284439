// Drives the web viewer in headless Chromium for tests/web.rs (no mocks: the real page from
// the real server). Usage: node page.mjs PLAYWRIGHT_DIR URL STATE [OTHER_ORIGIN_WT_URL CERT_HASH]
// Waits until window.snerf.state is STATE or 'error', prints the page's report as JSON.
// With OTHER_ORIGIN_WT_URL: instead opens a page of another origin (another loopback port)
// that tries a WebTransport session to the server, and prints its result.
import { launchChromium } from './launch.mjs';

const [pwDir, url, want, otherWt, certHash] = process.argv.slice(2);

const browser = await launchChromium(pwDir);
try {
  const page = await browser.newPage();
  page.on('console', (m) => console.error('page:', m.text()));
  page.on('pageerror', (e) => console.error('page error:', e.message));
  if (otherWt) {
    // Another origin on loopback (a public origin would be stopped by the browser's own
    // local-network rules before reaching the server, testing nothing of ours).
    const http = await import('node:http');
    const srv = http.createServer((_, res) => { res.setHeader('content-type', 'text/html'); res.end('<!doctype html><title>other</title>'); });
    await new Promise((res) => srv.listen(0, '127.0.0.1', res));
    await page.goto(`http://127.0.0.1:${srv.address().port}/`);
    srv.close();
    const r = await page.evaluate(async ([u, h]) => {
      const value = new Uint8Array(h.match(/../g).map((x) => parseInt(x, 16)));
      try {
        const wt = new WebTransport(u, { serverCertificateHashes: [{ algorithm: 'sha-256', value }] });
        await wt.ready;
        return { connected: true };
      } catch (e) {
        return { connected: false, error: String(e && e.message ? e.message : e) };
      }
    }, [otherWt, certHash]);
    console.log(JSON.stringify(r));
  } else {
    await page.goto(url);
    await page.waitForFunction((w) => window.snerf && (window.snerf.state === w || window.snerf.state === 'error'), want, { timeout: 240000, polling: 50 });
    // SNERF_WAIT_REFINED=1: then wait for the still view's full-resolution frame.
    if (process.env.SNERF_WAIT_REFINED === '1') {
      await page.waitForFunction(() => window.snerf.state === 'error' || (window.snerf.lastFrame && window.snerf.lastFrame.scale === 1 && window.snerf.lastFrame.complete), null, { timeout: 120000, polling: 50 });
    }
    const r = await page.evaluate(() => {
      const s = window.snerf;
      const out = { ...s, lastRender: null };
      if (s.lastRender) out.lastRender = { width: s.lastRender.width, height: s.lastRender.height, complete: s.lastRender.complete, rgba: Array.from(s.lastRender.rgba) };
      return out;
    });
    // What the canvas shows (the presented frame), as the browser composited it.
    if (r.state === want && (await page.locator('#view').isVisible())) {
      await page.evaluate(() => { document.getElementById('stats').style.display = 'none'; });
      // Playwright waits for the element to hold still over two animation frames; on a loaded
      // machine SwiftShader's frames come seconds apart, so allow more than its 30 s default.
      r.canvasPng = (await page.locator('#canvas').screenshot({ timeout: 120000 })).toString('base64');
    }
    console.log(JSON.stringify(r));
  }
} finally {
  await browser.close();
}
