// Refusals over WebTransport from a page of the server's own origin, while another page
// downloads an asset (for tests/web.rs). Usage: node refuse.mjs PLAYWRIGHT_DIR DOWNLOAD_URL
// PROBE_URL TOKEN. Page A opens DOWNLOAD_URL (the viewer streaming an asset); page B opens
// PROBE_URL (the viewer, no asset) and opens sessions that send a traversal name, an
// encoded traversal name, an oversized length, a frame that is not JSON, and a garbage
// datagram with a wrong token; each probe reports what it received. Prints
// {download: window.snerf of A, probes: [...]}.
import { launchChromium } from './launch.mjs';

const [pwDir, downloadUrl, probeUrl, token] = process.argv.slice(2);
const browser = await launchChromium(pwDir);
try {
  const a = await browser.newPage();
  const b = await browser.newPage();
  for (const [n, p] of [['A', a], ['B', b]]) p.on('pageerror', (e) => console.error(n, 'page error:', e.message));
  await a.goto(downloadUrl);
  await b.goto(probeUrl);
  await b.waitForFunction(() => window.snerf && (window.snerf.state === 'listed' || window.snerf.state === 'error'), null, { timeout: 120000 });
  const probes = await b.evaluate(async (token) => {
    const cfg = await (await fetch('/config.json')).json();
    const opts = cfg.cert_hash ? { serverCertificateHashes: [{ algorithm: 'sha-256', value: new Uint8Array(cfg.cert_hash.match(/../g).map((x) => parseInt(x, 16))) }] } : {};
    const te = new TextEncoder();
    const frame = (m) => { const j = te.encode(JSON.stringify(m)); const o = new Uint8Array(4 + j.length); new DataView(o.buffer).setUint32(0, j.length, true); o.set(j, 4); return o; };
    async function probe(name, send) {
      const out = { name, connected: false, control: '', dataStreams: 0, dataBytes: 0, closed: null };
      const wt = new WebTransport(cfg.webtransport, opts);
      try { await wt.ready; out.connected = true; } catch (e) { out.closed = 'connect failed: ' + e.message; return out; }
      const bidi = await wt.createBidirectionalStream();
      const w = bidi.writable.getWriter();
      (async () => {
        const r = bidi.readable.getReader();
        for (;;) { const { value, done } = await r.read(); if (done) break; out.control += new TextDecoder().decode(value); }
      })().catch(() => {});
      (async () => {
        const r = wt.incomingUnidirectionalStreams.getReader();
        for (;;) {
          const { value, done } = await r.read();
          if (done) break;
          out.dataStreams++;
          const rr = value.getReader();
          for (;;) { const x = await rr.read(); if (x.done) break; out.dataBytes += x.value.length; }
        }
      })().catch(() => {});
      await send(w, wt).catch((e) => { out.sendError = e.message; });
      out.closed = await Promise.race([
        wt.closed.then((i) => `closed ${i.closeCode}: ${i.reason}`, (e) => `failed: ${e.message}`),
        new Promise((r) => setTimeout(() => r('still open'), 5000)),
      ]);
      try { wt.close(); } catch {}
      return out;
    }
    const hello = (asset, tok) => frame({ type: 'hello', version: 1, token: tok ?? token, asset, have: [] });
    return [
      await probe('traversal', (w) => w.write(hello('../x'))),
      await probe('encoded traversal', (w) => w.write(hello('%2e%2e/x'))),
      await probe('absolute path', (w) => w.write(hello('/etc/passwd'))),
      await probe('oversized length', (w) => w.write(new Uint8Array([0xff, 0xff, 0xff, 0x7f, 1, 2, 3]))),
      await probe('not JSON', (w) => w.write(new Uint8Array([5, 0, 0, 0, 0x7b, 0x7b, 0x7b, 0x7b, 0x7b]))),
      await probe('unknown message', (w) => w.write(frame({ type: 'gimme', asset: 'scene' }))),
      await probe('garbage datagram, wrong token', async (w, wt) => {
        const d = wt.datagrams.writable.getWriter();
        await d.write(new Uint8Array([0x53, 0x50, 9, 9, 1, 2, 3]));
        await w.write(hello('scene', '00'.repeat(32)));
      }),
    ];
  }, token);
  await a.waitForFunction(() => window.snerf && (window.snerf.state === 'done' || window.snerf.state === 'error'), null, { timeout: 240000, polling: 50 });
  const download = await a.evaluate(() => ({ state: window.snerf.state, error: window.snerf.error, sha256: window.snerf.sha256, bytes: window.snerf.bytes, chunks: window.snerf.chunks }));
  console.log(JSON.stringify({ download, probes }));
} finally {
  await browser.close();
}
