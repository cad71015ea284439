// Headless Debian Chromium for the web viewer's tests and `snerf bench web`, one set of flags:
// WebGPU is behind --enable-unsafe-webgpu on Linux and SwiftShader provides the adapter
// without a GPU; presenting a WebGPU canvas needs the compositor on SwiftShader Vulkan too
// (with the default GL compositor the first present loses Dawn's instance). QUIC stays on.
import { createRequire } from 'module';

export const CHROMIUM_ARGS = ['--no-sandbox', '--disable-background-networking', '--disable-component-update', '--no-first-run',
  '--enable-unsafe-webgpu', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist', '--enable-gpu',
  '--enable-features=Vulkan', '--use-vulkan=swiftshader', '--use-angle=swiftshader'];

// SNERF_NO_WEBGPU=1: the same flags without --enable-unsafe-webgpu, so `requestAdapter()`
// returns null and the page draws with WebGL2, as in a browser without WebGPU.
export function chromiumArgs() {
  return process.env.SNERF_NO_WEBGPU === '1' ? CHROMIUM_ARGS.filter((a) => a !== '--enable-unsafe-webgpu') : CHROMIUM_ARGS;
}

// `pwDir`: a directory whose node_modules holds playwright-core (or playwright-core itself).
export async function launchChromium(pwDir) {
  const require = createRequire(pwDir + '/');
  const { chromium } = require('playwright-core');
  const browser = await chromium.launch({ executablePath: process.env.SNERF_CHROMIUM || '/usr/bin/chromium', headless: true, args: chromiumArgs() });
  // `snerf serve` serves the page over HTTPS with a self-signed certificate: every page takes
  // it as a person does by clicking through the browser's one-time warning.
  const newPage = browser.newPage.bind(browser), newContext = browser.newContext.bind(browser);
  // SNERF_NO_WEBTRANSPORT=1: every page loses `WebTransport` before its scripts run, as in a
  // browser without it (Safari, Firefox): the page streams over HTTPS requests instead.
  const noWt = process.env.SNERF_NO_WEBTRANSPORT === '1';
  browser.newPage = async (o = {}) => {
    const p = await newPage({ ignoreHTTPSErrors: true, ...o });
    if (noWt) await p.addInitScript('delete window.WebTransport;');
    return p;
  };
  browser.newContext = (o = {}) => newContext({ ignoreHTTPSErrors: true, ...o });
  return browser;
}
