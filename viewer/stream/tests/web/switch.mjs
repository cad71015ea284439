// Style switches in the web viewer, for tests/web.rs and `snerf bench web-switch`: opens URL
// (a style of a multi-style asset, streamed whole), waits until it is done, then presses the
// keys KEYS one after another ("2,1,2": styles 2, 1, 2), each once the switch before it is
// complete, and prints the page's report as JSON (its `switches`: per switch the times of
// the press, the welcome, the first colour record, the first frame with new colour, the
// complete view; bytes and records). With RELOAD_URL: then opens that URL in the same page
// as a switch did before switches by colour (a whole style, reloaded), and adds `reload`:
// the time from the navigation to its first frame and to its complete view.
// Usage: node switch.mjs PLAYWRIGHT_DIR URL KEYS [RELOAD_URL]
import { launchChromium } from './launch.mjs';

const [pwDir, url, keys, reloadUrl] = process.argv.slice(2);

const browser = await launchChromium(pwDir);
try {
  const page = await browser.newPage();
  page.on('console', (m) => console.error('page:', m.text()));
  page.on('pageerror', (e) => console.error('page error:', e.message));
  await page.goto(url);
  const settled = (w) => window.snerf && (window.snerf.state === w || window.snerf.state === 'error');
  await page.waitForFunction(settled, 'done', { timeout: 240000, polling: 50 });
  const presses = keys ? keys.split(',') : [];
  // As a person looks before pressing: the still view's full-resolution frame drawn (no march
  // in flight), the switch's tables made (the page does that while idle), the fade over.
  const idle = () => {
    const s = window.snerf;
    return s.state === 'error' || (s.switchReady && s.lastFrame && s.lastFrame.complete && s.lastFrame.scale === 1);
  };
  for (let i = 0; i < presses.length; i++) {
    await page.waitForFunction(idle, null, { timeout: 240000, polling: 20 });
    await page.waitForTimeout(400);
    if (await page.evaluate(() => window.snerf.state === 'error')) break;
    await page.keyboard.press(presses[i]);
    await page.waitForFunction((n) => {
      const s = window.snerf;
      const sw = s.switches && s.switches[n];
      return s.state === 'error' || (sw && (sw.state === 'error' || (sw.state === 'done' && sw.completeAt)));
    }, i, { timeout: 240000, polling: 20 });
  }
  const r = await page.evaluate(() => {
    const s = window.snerf;
    const out = { ...s, lastRender: null, benchFrames: undefined };
    // what the fade canvas holds (the frame a switch fades from): its mean channel value
    const f = document.getElementById('fade');
    if (f.width && f.height) {
      const d = f.getContext('2d').getImageData(0, 0, f.width, f.height).data;
      let sum = 0;
      for (let i = 0; i < d.length; i += 4) sum += d[i] + d[i + 1] + d[i + 2];
      out.fadeMean = sum / (3 * f.width * f.height);
    }
    if (s.lastRender) out.lastRender = { width: s.lastRender.width, height: s.lastRender.height, complete: s.lastRender.complete, rgba: Array.from(s.lastRender.rgba) };
    return out;
  });
  if (reloadUrl) {
    // (from another document: a URL that differs in its fragment alone would not reload)
    await page.goto('about:blank');
    const t0 = Date.now();
    await page.goto(reloadUrl);
    await page.waitForFunction(settled, 'done', { timeout: 240000, polling: 20 });
    r.reload = await page.evaluate((t) => {
      const s = window.snerf, o = performance.timeOrigin;
      return { firstFrameMs: o + s.firstFrameAt - t, completeMs: o + s.completeAt - t, bytes: s.bytes, error: s.error };
    }, t0);
  }
  console.log(JSON.stringify(r));
} finally {
  await browser.close();
}
