// What tint.js and page.js share: Chromium's flags for WebGPU headless, playwright-core, and
// one run of a page in a fresh browser with its JSON report.
'use strict';

const fs = require('fs');
const os = require('os');
const path = require('path');

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

// Opens a page in headless Chromium (`executable`, with its own profile, removed afterwards),
// runs `work(page)` and writes the report it returns to standard output as JSON, with the
// browser's version, the page's errors (uncaught exceptions and console errors) and the
// milliseconds taken; then closes `server` and exits: status 0 when the report was written,
// 3 when Chromium could not be started or `work` failed or returned `{ fatal }` (the message on
// stderr, after `tool`'s name). `viewport` is the page's size, where given.
async function reportFromPage({ tool, executable, server, viewport }, work) {
  if (!fs.existsSync(executable)) {
    process.stderr.write(`${tool}: no Chromium at ${executable} (Debian: apt-get install chromium)\n`);
    process.exit(3);
  }
  const { chromium } = playwright(tool);
  const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'strahl-chromium-'));
  const started = Date.now();
  let context;
  let status = 0;
  try {
    context = await chromium.launchPersistentContext(profile, {
      executablePath: executable,
      headless: true,
      args: CHROMIUM_FLAGS,
      ignoreDefaultArgs: ['--headless'],
      ...(viewport ? { viewport } : {}),
    });
    const page = context.pages()[0] || (await context.newPage());
    const pageErrors = [];
    page.on('pageerror', (e) => pageErrors.push(e.message));
    page.on('console', (m) => { if (m.type() === 'error') pageErrors.push(m.text()); });
    const report = await work(page);
    if (report.fatal) throw new Error(report.fatal);
    report.browser = context.browser() ? context.browser().version() : null;
    report.pageErrors = pageErrors;
    report.totalMs = Date.now() - started;
    process.stdout.write(`${JSON.stringify(report, null, 1)}\n`);
  } catch (e) {
    process.stderr.write(`${tool}: ${e.message}\n`);
    status = 3;
  } finally {
    if (context) await context.close().catch(() => {});
    server.close();
    fs.rmSync(profile, { recursive: true, force: true });
  }
  process.exit(status);
}

module.exports = { CHROMIUM_FLAGS, playwright, reportFromPage };
