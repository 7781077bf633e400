#!/usr/bin/env node
// Opens strahl's web page (a folder tools/build-web wrote) in headless Chromium's WebGPU
// (SwiftShader), served from 127.0.0.1, and either renders through its test hook or takes a
// screenshot of it.
//
//   node tools/browser/page.js render DIR JOBS OUTDIR [--chromium PATH]
//   node tools/browser/page.js screenshot DIR OUT.png [--scene FILE] [--mode M] [--samples N] [--chromium PATH]
//
// render: JOBS is a JSON file, a list of { "name", "scene" (the scene file's text; or "url",
// a scene the page serves, fetched with the files it names), "opts"
// ({ mode, spp, width, height, seed, max_depth }) }, each rendered by
// `window.strahl.render(scene, opts)`, its pixels written to OUTDIR/NAME.rgba (8-bit RGBA,
// row by row from the top); or with "rays" (8 numbers per ray, null for Infinity) and "opts"
// ({ all }), answered
// by `window.strahl.trace(scene, rays, opts)`, its columns written to OUTDIR/NAME.json. A JSON
// report goes to standard output: the adapter, the browser, and per job its milliseconds and
// size, or its error.
//
// screenshot: the page shows FILE (served beside the page as models/NAME; default the seed
// scene), in mode M (path or whitted; default the scene's), until it has N samples per pixel
// (default 16; Whitted renders once, at the scene's spp) or an error, then the page is saved
// as OUT.png; the report gives the page's status.
//
// Exit status: 0 when the report was written (the caller judges it), 2 for a usage error,
// 3 when Chromium, WebGPU or the page could not be started (message on stderr).
'use strict';

const fs = require('fs');
const http = require('http');
const path = require('path');
const { reportFromPage } = require('./chromium');

const USAGE = 'usage: node page.js render DIR JOBS OUTDIR | screenshot DIR OUT.png [--scene FILE] [--mode M] [--samples N]';

function usage(message) {
  process.stderr.write(`page.js: ${message}\n${USAGE}\n`);
  process.exit(2);
}

function parseArgs(argv) {
  const args = { chromium: process.env.CHROMIUM || '/usr/bin/chromium', scene: null, mode: null, samples: 16, positional: [] };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    if (a === '--chromium') args.chromium = argv[++i] || usage('--chromium needs a path');
    else if (a === '--scene') args.scene = argv[++i] || usage('--scene needs a file');
    else if (a === '--mode') {
      args.mode = argv[++i];
      if (!['path', 'whitted'].includes(args.mode)) usage('--mode takes path or whitted');
    }
    else if (a === '--samples') {
      args.samples = Number(argv[++i]);
      if (!Number.isInteger(args.samples) || args.samples < 1) usage('--samples needs a positive integer');
    } else if (a.startsWith('-')) usage(`unknown option ${a}`);
    else args.positional.push(a);
  }
  const [command, ...rest] = args.positional;
  const want = { render: 3, screenshot: 2 }[command];
  if (want === undefined) usage(command ? `unknown command ${command}` : 'no command given');
  if (rest.length !== want) usage(`${command} takes ${want} arguments, not ${rest.length}`);
  return { ...args, command, rest };
}

const TYPES = {
  '.html': 'text/html; charset=utf-8',
  '.js': 'text/javascript; charset=utf-8',
  '.css': 'text/css; charset=utf-8',
  '.wasm': 'application/wasm',
  '.toml': 'text/plain; charset=utf-8',
  '.glb': 'model/gltf-binary',
  '.gltf': 'model/gltf+json',
};

// Serves `dir`, and `extra` (a file) as /models/BASENAME, on 127.0.0.1 (a secure context, as
// WebGPU needs).
async function serve(dir, extra) {
  const server = http.createServer((req, res) => {
    const url = decodeURIComponent(new URL(req.url || '/', 'http://x').pathname);
    let file = null;
    if (extra && url === `/models/${path.basename(extra)}`) file = extra;
    else {
      const p = path.normalize(path.join(dir, url === '/' ? 'index.html' : url));
      if (p.startsWith(dir + path.sep) && fs.existsSync(p) && fs.statSync(p).isFile()) file = p;
    }
    if (!file) {
      res.writeHead(404);
      res.end();
      return;
    }
    res.writeHead(200, { 'content-type': TYPES[path.extname(file)] || 'application/octet-stream' });
    res.end(fs.readFileSync(file));
  });
  await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
  return { server, origin: `http://127.0.0.1:${server.address().port}/` };
}

// In the page: every job through window.strahl.render, the pixels as base64.
async function renderInPage(jobs) {
  const report = { adapter: null, jobs: [] };
  try {
    await window.strahl.ready;
  } catch (e) {
    return { fatal: `the page could not open WebGPU: ${e.message || e}` };
  }
  report.adapter = window.strahl.status().adapter;
  for (const job of jobs) {
    const t0 = performance.now();
    try {
      if (job.url) {
        // A scene the page serves, fetched with the files it names, as the view loads it.
        const { name, bytes, files } = await window.strahl.fetchScene(job.url);
        job.scene = bytes;
        job.opts = { ...(job.opts || {}), name, files };
      }
      if (job.rays) {
        // JSON has no Infinity: a null stands for it (a tmax without bound).
        const rays = job.rays.map((v) => (v === null ? Infinity : v));
        const h = await window.strahl.trace(job.scene, rays, job.opts || {});
        const columns = {};
        for (const [k, v] of Object.entries(h)) columns[k] = Array.from(v);
        report.jobs.push({ name: job.name, hits: h.t.length, ms: Math.round(performance.now() - t0), columns });
        continue;
      }
      const { width, height, rgba } = await window.strahl.render(job.scene, job.opts || {});
      let text = '';
      for (let i = 0; i < rgba.length; i += 0x8000) text += String.fromCharCode(...rgba.subarray(i, i + 0x8000));
      report.jobs.push({ name: job.name, width, height, ms: Math.round(performance.now() - t0), rgba: btoa(text) });
    } catch (e) {
      report.jobs.push({ name: job.name, error: String(e.message || e) });
    }
  }
  return report;
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  const dir = path.resolve(args.rest[0]);
  if (!fs.existsSync(path.join(dir, 'index.html'))) usage(`${dir} has no index.html: build it with tools/build-web ${args.rest[0]}`);
  const extra = args.scene ? path.resolve(args.scene) : null;
  if (extra && !fs.existsSync(extra)) usage(`no file ${extra}`);
  let jobs = null;
  if (args.command === 'render') {
    try {
      jobs = JSON.parse(fs.readFileSync(args.rest[1], 'utf8'));
    } catch (e) {
      usage(`cannot read the jobs ${args.rest[1]}: ${e.message}`);
    }
    fs.mkdirSync(args.rest[2], { recursive: true });
  }
  const { server, origin } = await serve(dir, extra);
  await reportFromPage({ tool: 'page.js', executable: args.chromium, server, viewport: { width: 1000, height: 560 } }, async (page) => {
    const query = new URLSearchParams();
    if (extra) query.set('scene', `models/${path.basename(extra)}`);
    if (args.mode) query.set('mode', args.mode);
    await page.goto(`${origin}index.html?${query}`);
    await page.waitForFunction(() => window.strahl !== undefined, null, { timeout: 60000 });
    if (args.command === 'screenshot') {
      await page.waitForFunction(
        ([n, whitted]) => { const s = window.strahl.status(); return s.error || (whitted ? s.samples > 0 : s.samples >= n); },
        [args.samples, args.mode === 'whitted'],
        { timeout: 600000, polling: 250 },
      );
      const report = { status: await page.evaluate(() => window.strahl.status()) };
      await page.screenshot({ path: args.rest[1] });
      return report;
    }
    const report = await page.evaluate(renderInPage, jobs);
    for (const job of report.jobs || []) {
      if (job.columns !== undefined) {
        fs.writeFileSync(path.join(args.rest[2], `${job.name}.json`), JSON.stringify(job.columns));
        delete job.columns;
      }
      if (job.rgba === undefined) continue;
      fs.writeFileSync(path.join(args.rest[2], `${job.name}.rgba`), Buffer.from(job.rgba, 'base64'));
      delete job.rgba;
    }
    return report;
  });
}

main();
