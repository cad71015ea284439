// A style the server adds while the page shows the asset, for tests/web.rs: opens URL (a
// style of a multi-style asset), waits until it is done and watching for new styles, prints
// "watching" on a line of its own, asks for the first painting the page offers (the test
// then adds that style), waits for the new style's swatch, presses the key of the newest style once the page could switch, waits for the
// switch, and prints the page's report as JSON (with `swatches`: the swatch buttons shown).
// Usage: node newstyle.mjs PLAYWRIGHT_DIR URL
import { launchChromium } from './launch.mjs';

const [pwDir, url] = process.argv.slice(2);

const browser = await launchChromium(pwDir);
try {
  const page = await browser.newPage();
  page.on('console', (m) => console.error('page:', m.text()));
  page.on('pageerror', (e) => console.error('page error:', e.message));
  await page.goto(url);
  const wait = (f, arg) => page.waitForFunction(f, arg, { timeout: 120000, polling: 50 });
  await wait(() => window.snerf && ((window.snerf.state === 'done' && window.snerf.watching) || window.snerf.state === 'error'));
  // (counted before the test is told to add the style: it may arrive at once)
  const before = await page.evaluate(() => (window.snerf.styles || []).length);
  // the paintings offered, and the first asked for
  const offered = await page.evaluate(() => Array.from(document.querySelectorAll('select.paintings option')).map((o) => o.value));
  console.log('watching');
  if (offered.length) await page.click('button.train');
  const swatches = (n) => window.snerf.state === 'error' || (window.snerf.stylesAdded >= 1 && document.querySelectorAll('.swatch').length === n);
  if (await page.evaluate(() => window.snerf.state !== 'error')) {
    await wait(swatches, before + 1);
    await wait(() => {
      const s = window.snerf;
      return s.state === 'error' || (s.switchReady && s.lastFrame && s.lastFrame.complete && s.lastFrame.scale === 1);
    });
    await page.keyboard.press(String(before + 1));
    await wait(() => {
      const s = window.snerf;
      const sw = s.switches && s.switches[0];
      return s.state === 'error' || (sw && (sw.state === 'error' || (sw.state === 'done' && sw.completeAt)));
    });
  }
  const r = await page.evaluate(() => ({
    ...window.snerf, lastRender: null, benchFrames: undefined,
    swatches: Array.from(document.querySelectorAll('.swatch')).map((b) => b.title),
    offeredAfter: Array.from(document.querySelectorAll('select.paintings option')).map((o) => o.value),
  }));
  r.offered = offered;
  console.log(JSON.stringify(r));
} finally {
  await browser.close();
}
