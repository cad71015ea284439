// Headless Debian Chromium for the web viewer's tests and `snerf bench web`, one set of flags:
// WebGPU is behind --enable-unsafe-webgpu on Linux and SwiftShader provides the adapter
// without a GPU; presenting a WebGPU canvas needs the compositor on SwiftShader Vulkan too
// (with the default GL compositor the first present loses Dawn's instance). QUIC stays on.
import { createRequire } from 'module';

export const CHROMIUM_ARGS = ['--no-sandbox', '--disable-background-networking', '--disable-component-update', '--no-first-run',
  '--enable-unsafe-webgpu', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist', '--enable-gpu',
  '--enable-features=Vulkan', '--use-vulkan=swiftshader', '--use-angle=swiftshader'];

// `pwDir`: a directory whose node_modules holds playwright-core (or playwright-core itself).
export async function launchChromium(pwDir) {
  const require = createRequire(pwDir + '/');
  const { chromium } = require('playwright-core');
  return chromium.launch({ executablePath: process.env.SNERF_CHROMIUM || '/usr/bin/chromium', headless: true, args: CHROMIUM_ARGS });
}
