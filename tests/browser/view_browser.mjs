// The live view in headless Chromium (puppeteer-core): node view_browser.mjs WEB_DIR CHROMIUM
// OUT_DIR FINISHED_URL FINISHED_DIR LIVE_URL LIVE_DIR. Checks, printing "ok ..." or "FAIL ..." lines
// and exiting 1 on any failure:
//  - the page loads and renders with no console error, page error or failed request;
//  - the points the page draws (window.rthsView.drawn.frf) equal frf.csv's (frequency_hz,
//    amplitude_m), number for number (the API sends %.17g, which round-trips);
//  - a screenshot (OUT_DIR/view_finished.png) is not blank: many distinct colours;
//  - on a run folder being appended to (LIVE_DIR, prepared by simulate_run.mjs with interval 0,
//    continued from here), the number of drawn points grows without a reload and ends equal to
//    journal.jsonl's; screenshot OUT_DIR/view_live.png.
import fs from "node:fs";
import path from "node:path";
import { spawn } from "node:child_process";
import { createRequire } from "node:module";
import { fileURLToPath } from "node:url";

const [webDir, chromium, outDir, finishedUrl, finishedDir, liveUrl, liveDir] = process.argv.slice(2);
const here = path.dirname(fileURLToPath(import.meta.url));
// puppeteer-core is web/'s devDependency (web/package-lock.json), installed by `make deps`
const puppeteer = createRequire(path.resolve(webDir, "package.json"))("puppeteer-core");
let failures = 0;
const ok = (m) => console.log(`ok   ${m}`);
const fail = (m) => {
  console.log(`FAIL ${m}`);
  failures++;
};

function readCsv(file) {
  const [head, ...rows] = fs.readFileSync(file, "utf8").trim().split("\n");
  const cols = head.split(",");
  return rows.map((r) => Object.fromEntries(r.split(",").map((v, i) => [cols[i], Number(v)])));
}

function journalPoints(dir) {
  return fs.readFileSync(path.join(dir, "journal.jsonl"), "utf8").split("\n").filter((l) => l.includes('"point"')).length;
}

function watch(page, label, problems) {
  page.on("console", (m) => {
    if (m.type() === "error" || m.type() === "warning") problems.push(`${label}: console ${m.type()}: ${m.text()}`);
  });
  page.on("pageerror", (e) => problems.push(`${label}: page error: ${e.message}`));
  page.on("requestfailed", (r) => {
    // the event stream is cut when the page is closed or navigated away: not a failure
    if (!r.url().endsWith("/api/events")) problems.push(`${label}: request failed: ${r.url()}`);
  });
  page.on("response", (r) => {
    if (r.status() >= 400) problems.push(`${label}: HTTP ${r.status()} for ${r.url()}`);
  });
}

// Distinct colours of a PNG, decoded by the browser itself (an <img> drawn on a canvas).
async function colours(page, png) {
  const url = `data:image/png;base64,${png.toString("base64")}`;
  return page.evaluate(async (src) => {
    const img = new Image();
    img.src = src;
    await img.decode();
    const c = document.createElement("canvas");
    c.width = img.width;
    c.height = img.height;
    const g = c.getContext("2d");
    g.drawImage(img, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    const seen = new Set();
    for (let i = 0; i < d.length; i += 4) seen.add((d[i] << 16) | (d[i + 1] << 8) | d[i + 2]);
    return seen.size;
  }, url);
}

async function drawnCount(page) {
  return page.evaluate(() => window.rthsView.drawn.frf.length);
}

async function finishedRun(browser) {
  const problems = [];
  const page = await browser.newPage();
  await page.setViewport({ width: 1400, height: 1000 });
  watch(page, "finished run", problems);
  await page.goto(finishedUrl, { waitUntil: "load" });
  await page.waitForFunction(() => window.rthsView && window.rthsView.renders > 0 && window.rthsView.drawn.frf.length > 0, { timeout: 15000 });
  await new Promise((r) => setTimeout(r, 800)); // the event stream's first change, then idle
  const drawn = await page.evaluate(() => window.rthsView.drawn.frf);
  const csv = readCsv(path.join(finishedDir, "frf.csv"));
  if (drawn.length !== csv.length) fail(`page draws ${drawn.length} points, frf.csv has ${csv.length}`);
  else {
    const bad = csv.findIndex((r, i) => r.frequency_hz !== drawn[i][0] || r.amplitude_m !== drawn[i][1]);
    if (bad >= 0) fail(`point ${bad}: page (${drawn[bad]}) != frf.csv (${csv[bad].frequency_hz}, ${csv[bad].amplitude_m})`);
    else ok(`the page draws frf.csv's ${csv.length} points exactly`);
  }
  const inside = await page.evaluate(() => window.rthsView.drawn.frfInside);
  if (inside !== csv.length) fail(`${csv.length - inside} of ${csv.length} points drawn outside the plot`);
  else ok("every point lies inside the plot's axes");
  const file = path.join(outDir, "view_finished.png");
  const png = await page.screenshot({ path: file, fullPage: true });
  const n = await colours(page, png);
  if (n < 200) fail(`screenshot ${file} looks blank: ${n} distinct colours`);
  else ok(`screenshot ${file}: ${n} distinct colours`);
  const badge = await page.$eval("#state", (e) => e.textContent);
  if (badge !== "ended") fail(`finished run shown as '${badge}'`);
  else ok("finished run shown as ended");
  await page.close();
  return problems;
}

async function liveRun(browser) {
  const problems = [];
  const page = await browser.newPage();
  await page.setViewport({ width: 1400, height: 1000 });
  watch(page, "run in progress", problems);
  await page.goto(liveUrl, { waitUntil: "load" });
  await page.waitForFunction(() => window.rthsView && window.rthsView.drawn.frf.length > 0, { timeout: 15000 });
  const first = await drawnCount(page);
  // the run goes on: a point and a new live.json every 400 ms (simulate_run.mjs)
  const sim = spawn(process.execPath, [path.join(here, "simulate_run.mjs"), finishedDir, liveDir, "0", "400"], { stdio: "inherit" });
  const seen = [first];
  for (let i = 0; i < 16; i++) {
    await new Promise((r) => setTimeout(r, 500));
    seen.push(await drawnCount(page));
  }
  sim.kill();
  // the last change reaches the page within a poll and a fetch; a loaded machine may take longer
  const inJournal = journalPoints(liveDir);
  await page.waitForFunction((n) => window.rthsView.drawn.frf.length === n, { timeout: 20000 }, inJournal).catch(() => {});
  seen.push(await drawnCount(page));
  const last = seen[seen.length - 1];
  const monotone = seen.every((v, i) => i === 0 || v >= seen[i - 1]);
  if (!(last > first && monotone)) fail(`drawn point count did not grow: ${seen.join(" ")}`);
  else ok(`drawn point count grew without a reload: ${seen.join(" ")}`);
  if (last !== inJournal) fail(`page draws ${last}, journal holds ${inJournal}`);
  else ok(`page follows the journal (${last} drawn, ${inJournal} in journal.jsonl)`);
  const hasLive = await page.evaluate(() => !!window.rthsView.state.live);
  if (!hasLive) fail("live.json not shown");
  else ok("live.json shown (residual, trace, Lissajous)");
  const file = path.join(outDir, "view_live.png");
  const png = await page.screenshot({ path: file, fullPage: true });
  const n = await colours(page, png);
  if (n < 200) fail(`screenshot ${file} looks blank: ${n} distinct colours`);
  else ok(`screenshot ${file}: ${n} distinct colours`);
  await page.close();
  return problems;
}

fs.mkdirSync(outDir, { recursive: true });
const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  args: ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run"],
});
try {
  const problems = [...(await finishedRun(browser)), ...(await liveRun(browser))];
  if (problems.length) problems.forEach((p) => fail(p));
  else ok("no console error, page error or failed request");
} catch (e) {
  fail(`browser test: ${e.stack || e}`);
} finally {
  await browser.close();
}
process.exit(failures ? 1 : 0);
