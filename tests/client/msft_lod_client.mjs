// Loads lodforge's MSFT_lod outputs in a real client, Babylon.js's glTF loader in headless Chromium, and checks
// that each reaches its finest LOD.
//
//   node tests/client/msft_lod_client.mjs OUT_DIR
//
// OUT_DIR is the output folder of a `lodforge run`; its lods.json names the MSFT_lod files and each level's
// triangles. Babylon loads an MSFT_lod chain progressively, coarsest first: its MSFT_lod extension raises
// onNodeLODsLoadedObservable with index 0 for the coarsest level and ids.length for the node itself (the finest).
// Per file the check is: the loader completes, that last index is reached, every level's meshes were shown (the
// triangles of the meshes Babylon enabled, one after the other, add up to the levels' triangles in lods.json),
// and the meshes left enabled hold the finest level's triangles (lods.json lods[0].triangles).
//
// Prints one JSON object per file and a summary line to stdout. Exit 0: every file reached its finest LOD;
// 1: some did not; 2: the check could not run (a broken page, no lods.json); 77: skipped, with the reason on
// stdout ("skip: ..."), when Chromium, puppeteer-core or the Babylon packages are absent.
//
// Looked up: the npm packages in $LODFORGE_NODE_MODULES, else <repo>/tools/node/node_modules (scripts/setup.sh
// installs them there); Chromium in $LODFORGE_CHROMIUM, else chromium or chromium-browser on the PATH.
// The files are served by a small HTTP server on 127.0.0.1 (an ephemeral port) for the run only.

import { createRequire } from 'node:module';
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const modulesDir = process.env.LODFORGE_NODE_MODULES || path.resolve(here, '..', '..', 'tools', 'node', 'node_modules');

function skip(why) {
  console.log(`skip: ${why}`);
  process.exit(77);
}

function fail(why) {
  console.error(`error: ${why}`);
  process.exit(2);
}

function findChromium() {
  const given = process.env.LODFORGE_CHROMIUM;
  if (given) return fs.existsSync(given) ? given : null;
  for (const name of ['chromium', 'chromium-browser']) {
    try {
      const p = execFileSync('sh', ['-c', `command -v ${name}`], { encoding: 'utf8' }).trim();
      if (p) return p;
    } catch {
      // not on the PATH
    }
  }
  return null;
}

const outDir = process.argv[2];
if (!outDir) fail('usage: node tests/client/msft_lod_client.mjs OUT_DIR');

const babylonJs = path.join(modulesDir, 'babylonjs', 'babylon.js');
const loadersJs = path.join(modulesDir, 'babylonjs-loaders', 'babylon.glTFFileLoader.js');
for (const f of [babylonJs, loadersJs]) {
  if (!fs.existsSync(f)) skip(`${f} not found (scripts/setup.sh installs babylonjs and babylonjs-loaders with npm)`);
}
let puppeteer;
try {
  puppeteer = createRequire(path.join(modulesDir, 'noop.js'))('puppeteer-core');
} catch {
  skip(`puppeteer-core not found in ${modulesDir} (scripts/setup.sh installs it with npm)`);
}
const chromium = findChromium();
if (!chromium) skip('Chromium not found (Debian package chromium; or set LODFORGE_CHROMIUM)');

const manifestPath = path.join(outDir, 'lods.json');
if (!fs.existsSync(manifestPath)) fail(`${manifestPath} not found: run lodforge first`);
const manifest = JSON.parse(fs.readFileSync(manifestPath, 'utf8'));
const files = [];
for (const asset of manifest.assets) {
  const lods = asset.lods;
  if (!lods.length || !lods[0].msft_lod) continue;
  files.push({ file: lods[0].msft_lod.file, levels: lods.length - 1, triangles: lods.map((l) => l.triangles) });
}

// /lib/* the two Babylon scripts, /out/* the output folder (nothing outside it), / the page.
const root = path.resolve(outDir);
const server = http.createServer((req, res) => {
  const url = decodeURIComponent(new URL(req.url, 'http://localhost').pathname);
  let file = null;
  if (url === '/') {
    res.writeHead(200, { 'content-type': 'text/html' });
    res.end('<!doctype html><html><body><canvas id="c" width="128" height="128"></canvas>' +
            '<script src="/lib/babylon.js"></script><script src="/lib/loaders.js"></script></body></html>');
    return;
  } else if (url === '/lib/babylon.js') {
    file = babylonJs;
  } else if (url === '/lib/loaders.js') {
    file = loadersJs;
  } else if (url.startsWith('/out/')) {
    const p = path.resolve(root, '.' + url.slice(4));
    if (p.startsWith(root + path.sep)) file = p;
  }
  if (!file || !fs.existsSync(file) || !fs.statSync(file).isFile()) {
    res.writeHead(404);
    res.end();
    return;
  }
  const types = { '.js': 'text/javascript', '.gltf': 'model/gltf+json', '.glb': 'model/gltf-binary' };
  res.writeHead(200, { 'content-type': types[path.extname(file)] || 'application/octet-stream' });
  fs.createReadStream(file).pipe(res);
});
await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
const base = `http://127.0.0.1:${server.address().port}`;

let browser;
let failures = 0;
try {
  browser = await puppeteer.launch({
    executablePath: chromium,
    headless: true,
    args: ['--no-sandbox', '--disable-gpu-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
           '--disable-dev-shm-usage'],
  });
  const page = await browser.newPage();
  const pageErrors = [];
  page.on('pageerror', (e) => pageErrors.push(String(e)));
  await page.goto(base + '/', { waitUntil: 'load' });
  for (const f of files) {
    const result = await page.evaluate(async (rootUrl, fileName) => {
      const canvas = document.getElementById('c');
      let engine;
      let engineKind;
      try {
        engine = new BABYLON.Engine(canvas, false);
        engineKind = 'webgl' + engine.webGLVersion;
      } catch (e) {
        engine = new BABYLON.NullEngine();  // no WebGL here: the loader runs all the same
        engineKind = 'null';
      }
      const scene = new BABYLON.Scene(engine);
      new BABYLON.ArcRotateCamera('camera', 0, 1, 10, BABYLON.Vector3.Zero(), scene);
      const events = [];
      const shown = [];
      const enabledTriangles = () => scene.meshes
          .filter((m) => !m.isDisposed() && m.isEnabled() && m.getTotalVertices() > 0)
          .reduce((n, m) => n + m.getTotalIndices() / 3, 0);
      let extension = false;
      // Subscribed when the plugin is activated, before it can complete: polling for the plugin could miss a
      // completion that comes first on a loaded machine.
      let markComplete;
      const completed = new Promise((resolve) => { markComplete = resolve; });
      const observer = BABYLON.SceneLoader.OnPluginActivatedObservable.add((plugin) => {
        if (plugin.name !== 'gltf') return;
        plugin.onCompleteObservable.addOnce(() => markComplete(true));
        // Every LOD node's mesh is created disabled and enabled once its level is loaded (the coarser one is
        // then disposed): the triangles of each enabled mesh, in order, are the levels as Babylon showed them.
        plugin.onMeshLoadedObservable.add((mesh) => {
          mesh.onEnabledStateChangedObservable.add((enabled) => {
            if (enabled && mesh.getTotalIndices() > 0) shown.push(mesh.getTotalIndices() / 3);
          });
        });
        plugin.onExtensionLoadedObservable.add((ext) => {
          if (ext.name !== 'MSFT_lod') return;
          extension = true;
          ext.onNodeLODsLoadedObservable.add((index) => events.push(index));
        });
      });
      try {
        await BABYLON.SceneLoader.ImportMeshAsync('', rootUrl, fileName, scene);
        const complete = await Promise.race([completed, new Promise((r) => setTimeout(() => r(false), 30000))]);
        scene.render();
        return { engine: engineKind, extension, complete, events, shown, triangles: enabledTriangles() };
      } catch (e) {
        return { engine: engineKind, error: String(e && e.message ? e.message : e) };
      } finally {
        BABYLON.SceneLoader.OnPluginActivatedObservable.remove(observer);
        scene.dispose();
        engine.dispose();
      }
    }, base + '/out/' + path.posix.dirname(f.file) + '/', path.posix.basename(f.file));
    const finest = f.levels;  // the node itself comes after its ids.length LOD nodes
    const reached = result.events && result.events.length > 0 && result.events[result.events.length - 1] === finest;
    // Each level shown once (a level that reuses the one before is a node of its own on the same mesh).
    const sum = (a) => a.reduce((n, x) => n + x, 0);
    const everyLevel = result.shown && sum(result.shown) === sum(f.triangles);
    const ok = !result.error && result.extension && result.complete && reached && everyLevel &&
               result.triangles === f.triangles[0];
    if (!ok) ++failures;
    console.log(JSON.stringify({
      file: f.file, ok, engine: result.engine, error: result.error, msft_lod_extension: result.extension,
      complete: result.complete, finest_index: finest,
      lod_indices_loaded: result.events, triangles_shown: result.shown,
      triangles_finally: result.triangles, triangles_expected: f.triangles[0],
      triangles_per_level: f.triangles,
    }));
  }
  if (pageErrors.length) console.log(JSON.stringify({ page_errors: pageErrors }));
} catch (e) {
  console.error(`error: ${e && e.stack ? e.stack : e}`);
  process.exitCode = 2;
} finally {
  if (browser) await browser.close();
  server.close();
}
if (process.exitCode !== 2) {
  console.log(`summary: ${files.length - failures} of ${files.length} MSFT_lod file(s) reached their finest LOD`);
  process.exitCode = failures ? 1 : 0;
}
