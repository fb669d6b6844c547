// A campaign folder's page in headless Chromium (puppeteer-core): node campaign_browser.mjs
// WEB_DIR CHROMIUM OUT_DIR URL CAMPAIGN_DIR LIVE_URL LIVE_DIR. Checks, printing "ok ..." or
// "FAIL ..." lines and exiting 1 on any failure:
//  - the page loads with no console error, page error or failed request, says "ended";
//  - the table holds campaign.csv's rows in run order, every run a link to its own page;
//    clicking a column header sorts by it (both ways), as sorting campaign.csv here does;
//  - the plot draws, for the chosen pair of columns, exactly campaign.csv's values of every run
//    (number for number: the API sends %.17g), for the default pair and after choosing another;
//  - a run's link opens that run's own page, which draws its frf.csv exactly and links back;
//  - a screenshot (OUT_DIR/campaign.png) is not blank;
//  - LIVE_DIR, a copy of the campaign whose campaign.csv is rewritten here run by run (as the
//    campaign does, temporary file then rename), is followed without a reload: the drawn points
//    grow to every run's.
import fs from "node:fs";
import path from "node:path";
import { createRequire } from "node:module";
import { drawsCsv, fail, ok, openPage, runInBrowser, screenshot } from "./browser_common.mjs";

const [webDir, chromium, outDir, url, dir, liveUrl, liveDir] = process.argv.slice(2);
const puppeteer = createRequire(path.resolve(webDir, "package.json"))("puppeteer-core");

// campaign.csv as rows of text (the campaign quotes no field of this plan)
function readCampaign(file) {
  const [head, ...rows] = fs.readFileSync(file, "utf8").trim().split("\n");
  const cols = head.split(",");
  return { cols, rows: rows.map((r) => Object.fromEntries(r.split(",").map((v, i) => [cols[i], v]))) };
}

const num = (v) => (v === "" ? null : Number(v));

// The page's drawn points equal campaign.csv's (x, y) of every run that has both.
async function drawsColumns(page, csv, x, y, label) {
  const drawn = await page.evaluate(() => window.rthsCampaign.drawn.points);
  const want = csv.rows.filter((r) => num(r[x]) != null && num(r[y]) != null).map((r) => [r.run, num(r[x]), num(r[y])]);
  const key = (p) => p.join(" ");
  const got = new Set(drawn.map(key));
  const missing = want.filter((p) => !got.has(key(p)));
  if (drawn.length !== want.length || missing.length)
    fail(`${label}: page draws ${drawn.length} points of (${x}, ${y}), campaign.csv has ${want.length}; first missing ${missing[0]}`);
  else ok(`${label}: the page draws campaign.csv's ${want.length} (${x}, ${y}) values exactly`);
}

async function finished(browser) {
  const problems = [];
  const csv = readCampaign(path.join(dir, "campaign.csv"));
  const page = await openPage(browser, url, "campaign", problems);
  await page.waitForFunction(() => window.rthsCampaign && window.rthsCampaign.drawn.rows.length > 0, { timeout: 15000 });
  await new Promise((r) => setTimeout(r, 800)); // the event stream's first change, then idle
  const badge = await page.$eval("#state", (e) => e.textContent);
  if (badge !== "ended") fail(`finished campaign shown as '${badge}'`);
  else ok("finished campaign shown as ended");

  // the table: every run, in run order, each a link to /runs/run_K/
  const rows = await page.evaluate(() => window.rthsCampaign.drawn.rows);
  const links = await page.$$eval("#runs a", (as) => as.map((a) => a.getAttribute("href")));
  const names = csv.rows.map((r) => r.run);
  if (rows.join() !== names.join()) fail(`table rows ${rows.join()} != campaign.csv's ${names.join()}`);
  else ok(`the table holds campaign.csv's ${names.length} runs in run order`);
  if (links.join() !== names.map((n) => `/runs/${n}/`).join()) fail(`links ${links.join()}`);
  else ok("every run links to its own page");
  const cells = await page.$$eval("#runs tbody tr:first-child td", (tds) => tds.map((t) => t.textContent));
  if (cells.length !== csv.cols.length || cells[0] !== names[0]) fail(`first row ${cells.join()}`);
  else ok(`the first row shows all ${cells.length} columns`);

  // sorting: by evaluations up, then down (ties in run order), as here
  const byEvaluations = (up) =>
    csv.rows
      .map((r, i) => [num(r.evaluations), i, r.run])
      .sort((a, b) => (up ? a[0] - b[0] : b[0] - a[0]) || a[1] - b[1])
      .map((t) => t[2])
      .join();
  for (const up of [true, false]) {
    await page.click('#runs th[data-column="evaluations"]');
    const sorted = (await page.evaluate(() => window.rthsCampaign.drawn.rows)).join();
    if (sorted !== byEvaluations(up)) fail(`sorted by evaluations ${up ? "up" : "down"}: ${sorted}`);
    else ok(`click on 'evaluations' sorts the runs ${up ? "up" : "down"}`);
  }

  // the plot: the default pair, then rig time against the PD gain
  const [x0, y0] = await page.evaluate(() => [window.rthsCampaign.state.x, window.rthsCampaign.state.y]);
  if (x0 !== csv.cols[1] || y0 !== "max_relative_error_vs_truth") fail(`default plot ${y0} against ${x0}`);
  await drawsColumns(page, csv, x0, y0, "default plot");
  await page.select("#y", "rig_time_s");
  await page.select("#x", "controller.kp_v_per_m");
  await drawsColumns(page, csv, "controller.kp_v_per_m", "rig_time_s", "chosen plot");
  await screenshot(page, path.join(outDir, "campaign.png"));

  // a run's own page, through its link
  const run = names[3];
  await Promise.all([page.waitForNavigation({ waitUntil: "load" }), page.click(`#runs a[href="/runs/${run}/"]`)]);
  await page.waitForFunction(() => window.rthsView && window.rthsView.drawn.frf.length > 0, { timeout: 15000 });
  if (!page.url().endsWith(`/runs/${run}/`)) fail(`the link opened ${page.url()}`);
  await drawsCsv(page, path.join(dir, run, "frf.csv"));
  const back = await page.$eval("#campaign-link", (a) => !a.hidden && a.getAttribute("href"));
  if (back !== "/") fail(`no link back to the campaign on ${run}'s page`);
  else ok(`${run}'s page links back to the campaign`);
  await screenshot(page, path.join(outDir, "campaign_run.png"));
  await page.close();
  return problems;
}

// campaign.csv rewritten as the campaign does after each run: the first k runs' results, the
// others' empty.
function writeProgress(full, k) {
  const lines = [full.cols.join(",")];
  full.rows.forEach((r, i) => {
    const keep = full.cols.indexOf("exit_status");
    const values = full.cols.map((c, j) => (i < k || j < keep ? r[c] : ""));
    lines.push(values.join(","));
  });
  const file = path.join(liveDir, "campaign.csv");
  fs.writeFileSync(`${file}.tmp`, `${lines.join("\n")}\n`);
  fs.renameSync(`${file}.tmp`, file);
}

async function growing(browser) {
  const problems = [];
  const full = readCampaign(path.join(dir, "campaign.csv"));
  writeProgress(full, 1);
  const page = await openPage(browser, liveUrl, "campaign in progress", problems);
  await page.waitForFunction(() => window.rthsCampaign && window.rthsCampaign.drawn.points.length === 1, { timeout: 15000 });
  const seen = [1];
  for (let k = 2; k <= full.rows.length; k++) {
    writeProgress(full, k);
    await new Promise((r) => setTimeout(r, 400));
    seen.push(await page.evaluate(() => window.rthsCampaign.drawn.points.length));
  }
  const n = full.rows.length;
  await page.waitForFunction((m) => window.rthsCampaign.drawn.points.length === m, { timeout: 20000 }, n).catch(() => {});
  seen.push(await page.evaluate(() => window.rthsCampaign.drawn.points.length));
  const monotone = seen.every((v, i) => i === 0 || v >= seen[i - 1]);
  if (!monotone || seen[seen.length - 1] !== n) fail(`drawn runs did not grow to ${n}: ${seen.join(" ")}`);
  else ok(`drawn runs grew without a reload: ${seen.join(" ")}`);
  await page.close();
  return problems;
}

await runInBrowser(puppeteer, chromium, outDir, "campaign pages", [finished, growing]);
