#!/usr/bin/env node
// Compiles every WGSL file of a folder with Tint, Chromium's WGSL compiler, in headless
// Chromium's WebGPU (SwiftShader), and prints a JSON report on standard output.
//
//   node tools/browser/tint.js [--modules-only] [--chromium PATH] DIR
//
// In one browser and one page, for each DIR/*.wgsl: device.createShaderModule and its
// getCompilationInfo() (errors and warnings, located), then one compute pipeline per
// `@compute` entry point of the file (layout 'auto'), each inside validation, internal and
// out-of-memory error scopes. The device is requested with the adapter's own storage-buffer
// and binding-size limits (WebGPU's defaults are lower), and the report gives those limits,
// so that a caller can tell a pipeline over the device's storage-buffer count from one Tint
// or Dawn refused.
//
// Exit status: 0 when the report was written (whatever it holds; the caller judges it),
// 2 for a usage error, 3 when Chromium or WebGPU could not be started (message on stderr).
//
// Chromium: $CHROMIUM, or --chromium, or /usr/bin/chromium. It is never downloaded.
// strahl-gpu's test `every_variant_compiles_in_tint` runs this script; the book's GPU
// chapter says how to run it by hand.
'use strict';

const fs = require('fs');
const http = require('http');
const path = require('path');
const { reportFromPage } = require('./chromium');

function usage(message) {
  process.stderr.write(`tint.js: ${message}\nusage: node tint.js [--modules-only] [--chromium PATH] DIR\n`);
  process.exit(2);
}

function parseArgs(argv) {
  const args = { modulesOnly: false, chromium: process.env.CHROMIUM || '/usr/bin/chromium', dir: null };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === '--modules-only') args.modulesOnly = true;
    else if (a === '--chromium') args.chromium = argv[++i] || usage('--chromium needs a path');
    else if (a.startsWith('-')) usage(`unknown option ${a}`);
    else if (args.dir === null) args.dir = a;
    else usage(`one folder only (also got ${a})`);
  }
  if (args.dir === null) usage('no folder given');
  return args;
}

// The `@compute` entry points of a WGSL text, in order (attributes may sit on lines of their
// own, as naga writes them).
function computeEntryPoints(text) {
  const found = [];
  const re = /@compute\b[^{;]*?\bfn\s+([A-Za-z_][A-Za-z0-9_]*)/g;
  let m;
  while ((m = re.exec(text)) !== null) found.push(m[1]);
  return found;
}

// What runs in the page: every module, one after another. `modules` is [{name, entryPoints}];
// the texts are fetched from the page's own origin.
async function checkInPage({ modules, modulesOnly }) {
  const started = performance.now();
  if (!navigator.gpu) return { fatal: 'navigator.gpu is missing: WebGPU is off in this browser' };
  const adapter = await navigator.gpu.requestAdapter();
  if (!adapter) return { fatal: 'requestAdapter() gave no adapter' };
  const wanted = ['maxStorageBuffersPerShaderStage', 'maxStorageBufferBindingSize', 'maxBufferSize'];
  const requiredLimits = {};
  for (const name of wanted) requiredLimits[name] = adapter.limits[name];
  let device;
  try {
    device = await adapter.requestDevice({ requiredLimits });
  } catch (e) {
    return { fatal: `requestDevice: ${e.message}` };
  }
  let lost = null;
  device.lost.then((info) => { lost = `${info.reason}: ${info.message}`; });
  const limits = {};
  for (const name of [...wanted, 'maxBindGroups', 'maxBindingsPerBindGroup', 'maxComputeInvocationsPerWorkgroup',
    'maxComputeWorkgroupStorageSize']) {
    limits[name] = device.limits[name];
  }
  const info = adapter.info || {};
  const report = {
    adapter: { vendor: info.vendor, architecture: info.architecture, device: info.device, description: info.description },
    limits,
    modules: [],
  };
  const scopes = ['validation', 'internal', 'out-of-memory'];
  const popAll = async () => {
    const errors = [];
    for (let i = 0; i < scopes.length; i++) {
      const e = await device.popErrorScope();
      if (e) errors.push(e.message);
    }
    return errors;
  };
  for (const m of modules) {
    const t0 = performance.now();
    const entry = { name: m.name, errors: [], warnings: [], pipelines: [] };
    report.modules.push(entry);
    const code = await (await fetch(`/wgsl/${encodeURIComponent(m.name)}`)).text();
    for (const s of scopes) device.pushErrorScope(s);
    const module = device.createShaderModule({ code, label: m.name });
    const compiled = await module.getCompilationInfo();
    for (const msg of compiled.messages) {
      const text = `${msg.lineNum}:${msg.linePos}: ${msg.message}`;
      if (msg.type === 'error') entry.errors.push(text);
      else entry.warnings.push(`${msg.type}: ${text}`);
    }
    const scoped = await popAll();
    // An error scope repeats what getCompilationInfo says; keep only what it adds.
    if (entry.errors.length === 0) entry.errors.push(...scoped);
    entry.compileMs = Math.round(performance.now() - t0);
    if (entry.errors.length > 0 || modulesOnly) continue;
    for (const entryPoint of m.entryPoints) {
      const t1 = performance.now();
      for (const s of scopes) device.pushErrorScope(s);
      device.createComputePipeline({ layout: 'auto', compute: { module, entryPoint }, label: `${m.name} ${entryPoint}` });
      const errors = await popAll();
      entry.pipelines.push({ entryPoint, ok: errors.length === 0, errors, ms: Math.round(performance.now() - t1) });
    }
    if (lost) break;
  }
  report.deviceLost = lost;
  device.destroy();
  report.pageMs = Math.round(performance.now() - started);
  return report;
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  const dir = path.resolve(args.dir);
  let names;
  try {
    names = fs.readdirSync(dir).filter((n) => n.endsWith('.wgsl')).sort();
  } catch (e) {
    usage(`cannot read ${dir}: ${e.message}`);
  }
  const modules = names.map((name) => ({ name, entryPoints: computeEntryPoints(fs.readFileSync(path.join(dir, name), 'utf8')) }));

  // WebGPU needs a secure context: a page served from 127.0.0.1 is one.
  const server = http.createServer((req, res) => {
    const url = decodeURIComponent(req.url || '/');
    if (url.startsWith('/wgsl/')) {
      const name = path.basename(url.slice('/wgsl/'.length));
      if (names.includes(name)) {
        res.writeHead(200, { 'content-type': 'text/plain; charset=utf-8' });
        res.end(fs.readFileSync(path.join(dir, name)));
        return;
      }
      res.writeHead(404);
      res.end();
      return;
    }
    res.writeHead(200, { 'content-type': 'text/html; charset=utf-8' });
    res.end('<!doctype html><title>tint.js</title><link rel="icon" href="data:,">');
  });
  await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
  const origin = `http://127.0.0.1:${server.address().port}/`;
  await reportFromPage({ tool: 'tint.js', executable: args.chromium, server }, async (page) => {
    await page.goto(origin);
    return page.evaluate(checkInPage, { modules, modulesOnly: args.modulesOnly });
  });
}

main();
