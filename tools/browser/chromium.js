// What tint.js and page.js share: Chromium's flags for WebGPU headless, and playwright-core.
'use strict';

// Chromium's flags for a WebGPU adapter headless (SwiftShader, since no GPU is assumed), on
// a machine whose network may be closed: nothing is fetched in the background.
const CHROMIUM_FLAGS = [
  '--headless=new',
  '--no-sandbox',
  '--enable-unsafe-webgpu',
  '--enable-gpu',
  '--use-angle=swiftshader',
  '--enable-features=Vulkan',
  '--use-vulkan=swiftshader',
  '--enable-unsafe-swiftshader',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--no-first-run',
  '--disable-quic',
];

// playwright-core (which drives the installed Chromium and never downloads one), or exit
// status 3 with what to run where it is not installed; `tool` names the caller in the message.
function playwright(tool) {
  try {
    return require('playwright-core');
  } catch (e) {
    process.stderr.write(`${tool}: playwright-core is missing: run npm ci in ${__dirname}\n`);
    process.exit(3);
  }
}

module.exports = { CHROMIUM_FLAGS, playwright };
