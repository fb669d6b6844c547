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
import path from "node:path";
import { spawn } from "node:child_process";
import { createRequire } from "node:module";
import { fileURLToPath } from "node:url";
import { drawsCsv, fail, journalPoints, ok, openPage, runInBrowser, screenshot } from "./browser_common.mjs";

const [webDir, chromium, outDir, finishedUrl, finishedDir, liveUrl, liveDir] = process.argv.slice(2);
const here = path.dirname(fileURLToPath(import.meta.url));
// puppeteer-core is web/'s devDependency (web/package-lock.json), installed by `make deps`
const puppeteer = createRequire(path.resolve(webDir, "package.json"))("puppeteer-core");

async function drawnCount(page) {
  return page.evaluate(() => window.rthsView.drawn.frf.length);
}

async function finishedRun(browser) {
  const problems = [];
  const page = await openPage(browser, finishedUrl, "finished run", problems);
  await page.waitForFunction(() => window.rthsView && window.rthsView.renders > 0 && window.rthsView.drawn.frf.length > 0, { timeout: 15000 });
  await new Promise((r) => setTimeout(r, 800)); // the event stream's first change, then idle
  await drawsCsv(page, path.join(finishedDir, "frf.csv"));
  // the health panel's integrity counts: frf.csv's columns summed over the points
  const integrity = await page.evaluate(() => window.rthsView.integrity);
  const rows = (await import("node:fs")).readFileSync(path.join(finishedDir, "frf.csv"), "utf8").trim().split("\n");
  const head = rows[0].split(",");
  const col = (name) => rows.slice(1).reduce((s, r) => s + Number(r.split(",")[head.indexOf(name)]), 0);
  const want = { late: col("late_samples"), clipped: col("clipped_demand_samples"), saturated: col("saturated_sensor_samples") };
  if (!integrity || head.indexOf("late_samples") < 0 || integrity.late !== want.late || integrity.clipped !== want.clipped || integrity.saturated !== want.saturated)
    fail(`integrity counts shown ${JSON.stringify(integrity)}, frf.csv has ${JSON.stringify(want)}`);
  else ok(`integrity counts shown as frf.csv has them (${JSON.stringify(want)})`);
  const file = path.join(outDir, "view_finished.png");
  await screenshot(page, file);
  const badge = await page.$eval("#state", (e) => e.textContent);
  if (badge !== "ended") fail(`finished run shown as '${badge}'`);
  else ok("finished run shown as ended");
  await page.close();
  return problems;
}

async function liveRun(browser) {
  const problems = [];
  const page = await openPage(browser, liveUrl, "run in progress", problems);
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
  await screenshot(page, file);
  await page.close();
  return problems;
}

await runInBrowser(puppeteer, chromium, outDir, "run pages", [finishedRun, liveRun]);
