// Drives report.html in headless Chromium (puppeteer-core).
//
//   node tests/browser/report_page.mjs check REPORT.html SCREENSHOT.png
//     opens the page, fails on any console error or page error, exercises search, class and status filters,
//     sorting and row expansion (with the LOD pictures, which must load, when the report lists any) and the
//     per-class overview, and writes a screenshot. Prints one line per check.
//   node tests/browser/report_page.mjs bench REPORT.html [REPS]
//     prints load, filter and sort times as JSON (best of REPS, default 3).
//
// Exit 0: passed; 1: a check failed; 77: cannot run here (puppeteer-core or Chromium missing), with the reason.
// Environment: LODFORGE_NODE_MODULES (default tools/node/node_modules of this checkout), CHROMIUM (default
// /usr/bin/chromium).
import { existsSync } from "node:fs";
import { createRequire } from "node:module";
import path from "node:path";
import { fileURLToPath, pathToFileURL } from "node:url";

const here = path.dirname(fileURLToPath(import.meta.url));
const modules = process.env.LODFORGE_NODE_MODULES || path.join(here, "..", "..", "tools", "node", "node_modules");
const chromium = process.env.CHROMIUM || "/usr/bin/chromium";

function skip(why) {
  console.log("SKIP: " + why);
  process.exit(77);
}

// Resolved the way node resolves it from that folder, whatever the package's internal layout (it moved in v24).
let entry;
try {
  entry = createRequire(path.join(modules, "noop.js")).resolve("puppeteer-core");
} catch {
  skip("puppeteer-core not found under " + modules + " (scripts/setup.sh installs it)");
}
if (!existsSync(chromium)) skip("Chromium not found at " + chromium + " (Debian package chromium)");
const imported = await import(pathToFileURL(entry).href);
const puppeteer = imported.default ?? imported;

const [mode, file, extra] = process.argv.slice(2);
if (!["check", "bench"].includes(mode) || !file) {
  console.error("usage: report_page.mjs check REPORT.html SCREENSHOT.png | bench REPORT.html [REPS]");
  process.exit(2);
}
const url = pathToFileURL(path.resolve(file)).href;

const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  args: ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run"],
});

async function open(page) {
  const t0 = performance.now();
  await page.goto(url, { waitUntil: "load", timeout: 120000 });
  await page.waitForFunction(() => {
    const c = document.getElementById("count") || document.getElementById("no-assets");
    return c && c.textContent !== "";
  }, { timeout: 120000 });
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => setTimeout(r, 0))));
  return performance.now() - t0;
}

// Time from the action to the next painted frame.
async function timed(page, action, arg) {
  return page.evaluate(async (action, arg) => {
    const untilFrame = () => new Promise((r) => requestAnimationFrame(() => setTimeout(r, 0)));
    const t0 = performance.now();
    if (action === "search") {
      const q = document.getElementById("q");
      q.value = arg;
      q.dispatchEvent(new Event("input"));
    } else if (action === "status" || action === "class") {
      const s = document.getElementById(action === "status" ? "st" : "cls");
      s.value = arg;
      s.dispatchEvent(new Event("change"));
    } else if (action === "sort") {
      document.querySelectorAll("#assets thead th")[arg].click();
    }
    await untilFrame();
    return performance.now() - t0;
  }, action, arg);
}

let failed = 0;
function check(ok, what) {
  console.log((ok ? "ok   " : "FAIL ") + what);
  if (!ok) failed++;
}

try {
  const page = await browser.newPage();
  await page.setViewport({ width: 1400, height: 1000 });
  const errors = [];
  page.on("console", (m) => { if (m.type() === "error") errors.push(m.text()); });
  page.on("pageerror", (e) => errors.push(String(e)));
  page.on("requestfailed", (r) => errors.push("request failed: " + r.url()));

  if (mode === "bench") {
    const reps = Number(extra || 3);
    const best = {};
    const keep = (k, v) => { best[k] = Math.min(best[k] ?? Infinity, v); };
    for (let r = 0; r < reps; r++) {
      keep("load_ms", await open(page));
      const rows = await page.evaluate(() => document.getElementById("count").textContent);
      keep("search_ms", await timed(page, "search", "set_01"));  // about 2.5% of the synthetic paths
      keep("search_clear_ms", await timed(page, "search", ""));
      keep("status_filter_ms", await timed(page, "status", "missed"));
      keep("status_clear_ms", await timed(page, "status", ""));
      keep("class_filter_ms", await timed(page, "class", "0"));
      keep("class_clear_ms", await timed(page, "class", ""));
      keep("sort_ms", await timed(page, "sort", 8));          // worst Hausdorff
      keep("sort_reverse_ms", await timed(page, "sort", 8));
      keep("sort_path_ms", await timed(page, "sort", 2));     // asset path
      best.count = rows;
    }
    best.console_errors = errors.length;
    console.log(JSON.stringify(best));
  } else {
    await open(page);
    const total = await page.evaluate(() => document.querySelectorAll("#assets tbody tr").length);
    check(total > 0, "the table shows rows (" + total + ")");
    const first = await page.evaluate(() => {
      const cell = document.querySelector("#assets tbody tr td.path");
      return cell ? cell.getAttribute("title") : null;
    });
    check(!!first, "the first row names its asset (" + first + ")");
    // Search: the first asset's file name finds it.
    const name = first ? first.split("/").pop() : "";
    await timed(page, "search", name);
    const found = await page.evaluate(() => Array.from(document.querySelectorAll("#assets tbody tr td.path"))
      .map((c) => c.getAttribute("title")));
    check(found.length >= 1 && found.every((p) => p.toLowerCase().includes(name.toLowerCase())),
      "search '" + name + "' keeps only matching rows (" + found.length + ")");
    await timed(page, "search", "no-such-asset-anywhere");
    check(await page.evaluate(() => document.querySelectorAll("#assets tbody tr").length === 0),
      "a search that matches nothing empties the table");
    await timed(page, "search", "");
    // Class filter: every row of the first class has that class.
    const cls = await page.evaluate(() => {
      const o = document.querySelector("#cls option[value='0']");
      return o ? o.textContent : null;
    });
    if (cls !== null) {
      await timed(page, "class", "0");
      const classes = await page.evaluate(() => Array.from(document.querySelectorAll("#assets tbody tr"))
        .map((r) => r.cells[3].textContent));
      check(classes.length > 0 && classes.every((c) => c === cls), "class filter '" + cls + "' (" + classes.length + " rows)");
      await timed(page, "class", "");
    }
    // Status filter: ok rows only say ok; failed rows only failed.
    for (const [value, text] of [["ok", "ok"], ["failed", "failed"], ["missed", "budget missed"]]) {
      await timed(page, "status", value);
      const st = await page.evaluate(() => Array.from(document.querySelectorAll("#assets tbody tr"))
        .map((r) => r.cells[4].textContent));
      check(st.every((s) => s === text), "status filter '" + value + "' (" + st.length + " rows)");
    }
    await timed(page, "status", "");
    // Sort by asset path, ascending.
    await timed(page, "sort", 2);
    const paths = await page.evaluate(() => Array.from(document.querySelectorAll("#assets tbody tr td.path"))
      .map((c) => c.getAttribute("title").toLowerCase()));
    check(paths.every((p, i) => i === 0 || paths[i - 1] <= p), "sorting by asset orders the paths");
    await timed(page, "sort", 1);  // back to the worst-first rank
    // Expand the first asset with LODs: a LOD table and the error/triangles plot with a connected chain.
    const expanded = await page.evaluate(async () => {
      const rows = Array.from(document.querySelectorAll("#assets tbody tr"));
      const row = rows.find((r) => Number(r.cells[5].textContent) > 0);
      if (!row) return null;
      row.querySelector("button.toggle").click();
      await new Promise((r) => requestAnimationFrame(() => setTimeout(r, 0)));
      const detail = document.querySelector("#assets tr.expanded");
      if (detail) detail.previousElementSibling.scrollIntoView({ block: "center" });  // the click redrew the rows
      return detail && {
        lods: detail.querySelectorAll("table.lods tbody tr").length,
        svg: detail.querySelectorAll("svg.chain").length,
        line: (detail.querySelector("svg.chain polyline.haus") || { getAttribute: () => "" }).getAttribute("points"),
        expected: Number(row.cells[5].textContent),
      };
    });
    check(!!expanded && expanded.lods === expanded.expected, "expanding a row lists its LODs");
    check(!!expanded && expanded.svg === 1 && expanded.line.split(" ").length >= 2,
      "the expanded row plots its chain (" + (expanded ? expanded.line : "") + ")");
    // Pictures: when the report lists any, expanding an asset that has them shows them, and every one loads.
    const pictures = await page.evaluate(async () => {
      const data = JSON.parse(document.getElementById("report-data").textContent);
      const listed = data.pic.reduce((x, y) => x + y, 0);
      if (!listed) return { listed };
      const rank = data.pic.findIndex((p) => p > 0);
      document.getElementById("q").value = data.name[rank];  // bring that asset's row onto the page
      document.getElementById("q").dispatchEvent(new Event("input"));
      const row = Array.from(document.querySelectorAll("#assets tbody tr[data-asset]"))
        .find((r) => Number(r.getAttribute("data-asset")) === rank);
      if (!row) return { listed, row: false };
      if (row.querySelector("button.toggle").getAttribute("aria-expanded") !== "true") row.querySelector("button.toggle").click();
      const imgs = () => Array.from(document.querySelectorAll("#assets tr.expanded div.pics img"));
      if (imgs().length) imgs()[0].scrollIntoView({ block: "center" });
      const t0 = performance.now();
      while (performance.now() - t0 < 20000 && !imgs().every((i) => i.complete)) {
        await new Promise((r) => setTimeout(r, 50));
      }
      return { listed, row: true, expected: data.pic[rank], shown: imgs().length,
               loaded: imgs().filter((i) => i.complete && i.naturalWidth > 0 && i.naturalWidth <= 256).length,
               src: imgs().length ? imgs()[0].getAttribute("src") : "" };
    });
    if (pictures.listed) {
      check(pictures.row && pictures.shown === pictures.expected && pictures.loaded === pictures.expected,
        "the expanded row shows its LOD pictures and they load (" + pictures.loaded + " of " + pictures.expected +
        " loaded, " + pictures.src + ")");
      await page.screenshot({ path: extra, captureBeyondViewport: false });  // the open row and its pictures
      await timed(page, "search", "");
    } else {
      await page.screenshot({ path: extra, captureBeyondViewport: false });
      console.log("note the report lists no LOD pictures");
    }
    // The per-class overview: opening it draws one canvas per class with LODs, every one with points.
    const overview = await page.evaluate(async () => {
      const d = document.getElementById("overview");
      if (!d) return null;
      d.open = true;
      await new Promise((r) => requestAnimationFrame(() => setTimeout(r, 50)));
      const data = JSON.parse(document.getElementById("report-data").textContent);
      const classes = new Set();
      let off = 0;
      data.nl.forEach((nl, a) => {
        for (let k = off; k < off + nl; k++) if (data.tri[k] > 0 && data.h[k] !== null) classes.add(data.cls[a]);
        off += nl;
      });
      const canvases = Array.from(d.querySelectorAll("canvas.overview"));
      return { expected: classes.size, canvases: canvases.length,
               points: canvases.map((c) => Number(c.getAttribute("data-points"))) };
    });
    check(!!overview && overview.canvases === overview.expected && overview.points.every((p) => p > 0),
      "the per-class overview draws every class (" + JSON.stringify(overview) + ")");
    await page.evaluate(() => document.getElementById("overview").scrollIntoView());
    await page.screenshot({ path: extra.replace(/\.png$/, "") + "-overview.png", captureBeyondViewport: false });
    check(errors.length === 0, "no console errors" + (errors.length ? ": " + errors.join(" | ") : ""));
  }
} catch (e) {
  console.log("FAIL " + (e && e.stack ? e.stack : e));
  failed++;
} finally {
  await browser.close();
}
process.exit(failed ? 1 : 0);
