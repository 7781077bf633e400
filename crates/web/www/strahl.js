// The page: strahl's GPU renderer (the wasm module crates/web builds, in pkg/) on WebGPU,
// with a panel like `strahl view`'s, and `window.strahl` for scripts:
//
//   await strahl.ready;                                    // WebGPU open (rejects if it cannot be)
//   const { width, height, rgba } = await strahl.render(sceneText, { mode, spp, width, height, seed, max_depth });
//   await strahl.load(name, bytes, files);                 // show a file (TOML, .gltf, .glb) in the view
//   const hits = await strahl.trace(sceneText, rays, { all });  // rays: 8 numbers each, as strahl trace's CSV
//   const { name, bytes, files } = await strahl.fetchScene(url);  // a scene and the files it names
//   strahl.status();                                       // { scene, samples, error, adapter }
//
// `rgba` is a Uint8Array of 8-bit sRGB pixels, row by row from the top, as in the PNG
// `strahl render` writes of the same text (with alpha 255). Options left out are the scene's.
// A page has no file system: the files a scene refers to (meshes, glTF buffers, images) come
// with it, as `files` (an object or a list of pairs: path → bytes or text, the path as the
// scene names it from `opts.name`'s folder, or `load`'s `name`'s). The view fetches those of a
// scene it loads by URL itself.
import init, { Renderer, hold_file, release_files } from './pkg/strahl_web.js';

const $ = (id) => document.getElementById(id);
const canvas = $('canvas');
const ctx2d = canvas.getContext('2d');

let renderer = null;
let scene = null;       // the loaded Scene (wasm)
let sceneName = null;
let view = null;        // Progressive (path mode) while one runs
let generation = 0;     // bumped by every restart, so that a stale frame loop stops
let lastError = null;
let samplesShown = 0;
let loopOf = -1;        // the generation whose frame loop runs, -1 when none does
let firstMode = null;   // ?mode= of the page's address, for the first scene

function showError(e) {
  lastError = e ? String(e.message || e) : null;
  $('error').hidden = !lastError;
  $('error').textContent = lastError || '';
}

function settings() {
  return {
    mode: document.querySelector('input[name=mode]:checked').value,
    maxDepth: Number($('max-depth').value),
    scale: Number($('scale').value),
    limit: Math.max(1, Math.min(65536, Math.round(Number($('limit').value)) || 1)),
  };
}

function draw(rgba, width, height) {
  if (canvas.width !== width || canvas.height !== height) {
    canvas.width = width;
    canvas.height = height;
  }
  ctx2d.putImageData(new ImageData(new Uint8ClampedArray(rgba.buffer, rgba.byteOffset, rgba.byteLength), width, height), 0, 0);
}

function stopView() {
  generation += 1;
  if (view) {
    view.free();
    view = null;
  }
}

// Starts rendering the loaded scene with the panel's settings: path mode adds samples frame
// by frame up to the sample limit; Whitted mode renders once at the scene's spp.
function restart() {
  stopView();
  if (!scene) return;
  const s = settings();
  const width = Math.max(1, Math.round(scene.width * s.scale));
  const height = Math.max(1, Math.round(scene.height * s.scale));
  $('size').textContent = `${width} × ${height}`;
  $('samples').textContent = '0';
  $('rate').textContent = '-';
  samplesShown = 0;
  const mine = generation;
  if (s.mode === 'whitted') {
    const t0 = performance.now();
    renderer.render_view(scene, width, height, s.maxDepth).then((frame) => {
      if (mine !== generation) return frame.free();
      draw(frame.rgba, frame.width, frame.height);
      frame.free();
      samplesShown = scene.spp;
      $('samples').textContent = `${scene.spp} (whitted)`;
      $('rate').textContent = (width * height * scene.spp / (performance.now() - t0) / 1e3).toFixed(2);
    }, showError);
    return;
  }
  try {
    view = renderer.progressive(scene, width, height, s.maxDepth);
  } catch (e) {
    showError(e);
    return;
  }
  startLoop(mine, width, height);
}

function startLoop(mine, width, height) {
  if (loopOf === mine) return;
  loopOf = mine;
  frameLoop(mine, width, height, 1);
}

// One frame of path tracing: `batch` sample passes, then the mean is read back and drawn;
// the batch grows or shrinks to keep a frame near 100 ms.
async function frameLoop(mine, width, height, batch) {
  const limit = settings().limit;
  const stop = () => { if (loopOf === mine) loopOf = -1; };
  if (mine !== generation || !view || view.samples >= limit) return stop();
  const n = Math.min(batch, limit - view.samples);
  const t0 = performance.now();
  try {
    view.add_samples(n);
    const rgba = await view.rgba();
    if (mine !== generation) return stop();
    const ms = Math.max(1, performance.now() - t0);
    draw(rgba, width, height);
    samplesShown = view.samples;
    $('samples').textContent = `${view.samples} / ${limit}`;
    $('rate').textContent = (width * height * n / ms / 1e3).toFixed(2);
    batch = Math.max(1, Math.min(64, Math.round(n * 100 / ms)));
  } catch (e) {
    showError(e);
    return stop();
  }
  requestAnimationFrame(() => frameLoop(mine, width, height, batch));
}

const encoder = new TextEncoder();
const asBytes = (b) => (typeof b === 'string' ? encoder.encode(b) : b);

// `renderer.load` of the file `name` with the files it refers to held meanwhile.
function loadWith(name, bytes, files) {
  const pairs = files ? (Array.isArray(files) ? files : Object.entries(files)) : [];
  try {
    for (const [path, b] of pairs) hold_file(path, asBytes(b));
    return renderer.load(name, asBytes(bytes));
  } finally {
    release_files();
  }
}

// Shows the file `name` with contents `bytes` (a Uint8Array) in the view.
async function load(name, bytes, files) {
  await ready;
  showError(null);
  let loaded;
  try {
    loaded = loadWith(name, bytes, files);
  } catch (e) {
    showError(e);
    throw e;
  }
  stopView();
  if (scene) scene.free();
  scene = loaded;
  sceneName = name;
  $('scene-name').textContent = name;
  $('summary').textContent = scene.summary;
  $('max-depth').value = scene.max_depth;
  $('max-depth-out').textContent = scene.max_depth;
  $('fov').value = scene.fov_y;
  $('fov-out').textContent = Math.round(scene.fov_y);
  const w = $('warnings');
  w.replaceChildren(...scene.warnings.map((line) => Object.assign(document.createElement('li'), { textContent: line })));
  const mode = firstMode || scene.mode;
  firstMode = null;
  document.querySelector(`input[name=mode][value=${mode}]`).checked = true;
  restart();
}

async function fetchBytes(url) {
  const response = await fetch(url);
  if (!response.ok) throw new Error(`${url}: ${response.status} ${response.statusText}`);
  return new Uint8Array(await response.arrayBuffer());
}

// A URL's path as strahl names the file (without the leading slash): a scene's references
// resolve against it as against a folder.
const pathOf = (url) => decodeURIComponent(url.pathname).replace(/^\/+/, '');

// The relative references of a scene file's text: a TOML file's `file`, `texture` and
// `radiance_texture` strings, a .gltf file's buffer and image URIs that are not data: URIs.
function references(name, bytes) {
  const text = new TextDecoder().decode(bytes);
  if (/\.gltf$/i.test(name)) {
    try {
      const json = JSON.parse(text);
      return [...(json.buffers || []), ...(json.images || [])]
        .map((x) => x.uri).filter((u) => typeof u === 'string' && !u.startsWith('data:'));
    } catch (e) {
      return [];
    }
  }
  if (/\.glb$/i.test(name)) return [];
  return [...text.matchAll(/^\s*(?:file|texture|radiance_texture)\s*=\s*"([^"]*)"/gm)].map((m) => m[1]);
}

// The scene at `url` and, two levels deep (a TOML file naming a .gltf naming its buffers),
// the files it refers to: { name, bytes, files } for `load`, `render` and `trace`.
async function fetchScene(url) {
  const base = new URL(url, location.href);
  const bytes = await fetchBytes(base);
  const files = [];
  let pending = [[base, bytes]];
  for (let depth = 0; depth < 2 && pending.length > 0; depth++) {
    const next = [];
    for (const [from, b] of pending) {
      for (const ref of references(pathOf(from), b)) {
        const u = new URL(ref, from);
        const got = await fetchBytes(u);
        files.push([pathOf(u), got]);
        next.push([u, got]);
      }
    }
    pending = next;
  }
  return { name: pathOf(base), bytes, files };
}

async function loadUrl(url) {
  showError(null);
  try {
    const { name, bytes, files } = await fetchScene(url);
    await load(name, bytes, files);
  } catch (e) {
    showError(e);
  }
}

// Dropped or opened files: the first scene file among them, the others held beside it.
async function loadFiles(list) {
  try {
    const all = await Promise.all([...list].map(async (f) => [f.name, new Uint8Array(await f.arrayBuffer())]));
    const scene = all.find(([n]) => /\.(toml|gltf|glb)$/i.test(n)) || all[0];
    await load(scene[0], scene[1], all.filter((f) => f !== scene));
  } catch (e) {
    showError(e);
  }
}

// The test hook: renders `sceneText` (TOML, or the file `opts.name` names) on its own,
// beside whatever the view shows.
async function render(sceneText, opts = {}) {
  await ready;
  const s = loadWith(opts.name || 'scene.toml', sceneText, opts.files);
  try {
    const frame = await renderer.render(s, opts.mode, opts.spp, opts.width, opts.height, opts.seed, opts.max_depth);
    const out = { width: frame.width, height: frame.height, rgba: frame.rgba };
    frame.free();
    return out;
  } finally {
    s.free();
  }
}

// The test hook for ray queries: `rays` holds 8 numbers per ray (ox, oy, oz, dx, dy, dz,
// tmin, tmax); the answer's columns are those of `strahl trace` (`ray_splits` as offsets).
async function trace(sceneText, rays, opts = {}) {
  await ready;
  const s = loadWith(opts.name || 'scene.toml', sceneText, opts.files);
  try {
    const h = await renderer.trace(s, Float64Array.from(rays), !!opts.all);
    const out = {
      ray_splits: h.ray_splits, t: h.t, object: h.object, face: h.face, primitive: h.primitive, enter: h.enter, normal: h.normal,
    };
    h.free();
    return out;
  } finally {
    s.free();
  }
}

function status() {
  return { scene: sceneName, samples: samplesShown, error: lastError, adapter: adapterName };
}

// wgpu names a browser's adapter only by its backend; the browser's own description says more.
let adapterName = null;
const ready = (async () => {
  await init();
  renderer = await Renderer.open();
  const info = navigator.gpu ? ((await navigator.gpu.requestAdapter()) || {}).info : null;
  adapterName = info ? [info.vendor, info.architecture, info.description].filter((x) => x).join(' ') || 'WebGPU' : 'WebGPU';
  $('adapter').textContent = `${adapterName} (WebGPU)`;
  $('limits').textContent = renderer.limits;
})();
ready.catch((e) => {
  $('adapter').textContent = 'none';
  showError(e);
});

window.strahl = { ready, render, trace, load, fetchScene, status };

// The camera, moved as in `strahl view`: left drag orbits, right or middle drag pans, the
// wheel zooms; each move restarts the image (at most once per animation frame).
let restartPending = false;
function restartSoon() {
  if (restartPending) return;
  restartPending = true;
  requestAnimationFrame(() => { restartPending = false; restart(); });
}
let drag = null;
canvas.addEventListener('pointerdown', (e) => {
  if (!scene) return;
  drag = { x: e.clientX, y: e.clientY, pan: e.button !== 0 };
  canvas.setPointerCapture(e.pointerId);
});
canvas.addEventListener('pointermove', (e) => {
  if (!drag || !scene) return;
  const dx = e.clientX - drag.x;
  const dy = e.clientY - drag.y;
  drag.x = e.clientX;
  drag.y = e.clientY;
  if (drag.pan) scene.pan(dx, dy, canvas.clientHeight);
  else scene.orbit(dx * 0.01, dy * 0.01);
  restartSoon();
});
canvas.addEventListener('pointerup', () => { drag = null; });
canvas.addEventListener('contextmenu', (e) => e.preventDefault());
canvas.addEventListener('wheel', (e) => {
  if (!scene) return;
  e.preventDefault();
  scene.zoom(Math.exp(e.deltaY * 0.002));
  restartSoon();
}, { passive: false });
function resetCamera() {
  if (!scene) return;
  scene.reset_camera();
  $('fov').value = scene.fov_y;
  $('fov-out').textContent = Math.round(scene.fov_y);
  restart();
}
$('reset').addEventListener('click', resetCamera);
document.addEventListener('keydown', (e) => { if ((e.key === 'r' || e.key === 'R') && e.target.tagName !== 'INPUT') resetCamera(); });
$('fov').addEventListener('input', () => {
  $('fov-out').textContent = $('fov').value;
  if (scene) { scene.fov_y = Number($('fov').value); restartSoon(); }
});

// The panel.
for (const [input, output] of [['max-depth', 'max-depth-out'], ['scale', 'scale-out']]) {
  $(input).addEventListener('input', () => { $(output).textContent = $(input).value; });
  $(input).addEventListener('change', restart);
}
for (const r of document.querySelectorAll('input[name=mode]')) r.addEventListener('change', restart);
// A higher limit goes on from the samples there are.
$('limit').addEventListener('change', () => {
  if (view && settings().mode === 'path') startLoop(generation, canvas.width, canvas.height);
});
$('file').addEventListener('change', (e) => { if (e.target.files.length > 0) loadFiles(e.target.files); });
$('url-form').addEventListener('submit', (e) => { e.preventDefault(); if ($('url').value) loadUrl($('url').value); });
$('save').addEventListener('click', () => {
  canvas.toBlob((blob) => {
    const a = document.createElement('a');
    a.href = URL.createObjectURL(blob);
    a.download = `${(sceneName || 'strahl').replace(/\.[^.]*$/, '')}.png`;
    a.click();
    setTimeout(() => URL.revokeObjectURL(a.href), 1000);
  }, 'image/png');
});
const viewArea = $('view');
for (const type of ['dragenter', 'dragover']) {
  document.addEventListener(type, (e) => { e.preventDefault(); viewArea.classList.add('drop'); });
}
document.addEventListener('dragleave', () => viewArea.classList.remove('drop'));
document.addEventListener('drop', (e) => {
  e.preventDefault();
  viewArea.classList.remove('drop');
  if (e.dataTransfer.files.length > 0) loadFiles(e.dataTransfer.files);
});

// The shipped scenes tools/build-web lists, to choose from.
fetch('scenes/index.json').then((r) => (r.ok ? r.json() : [])).then((names) => {
  const select = $('shipped');
  for (const n of names) select.append(Object.assign(document.createElement('option'), { value: `scenes/${n}`, textContent: n }));
  select.addEventListener('change', () => { if (select.value) loadUrl(select.value); });
}, () => {});

// The first scene: ?scene=URL, else the seed scene; in ?mode=path or whitted, else the scene's.
const query = new URLSearchParams(location.search);
firstMode = ['path', 'whitted'].includes(query.get('mode')) ? query.get('mode') : null;
loadUrl(query.get('scene') || 'scenes/seed.toml');
