import fs from "node:fs";

// What the browser tests share: ok/FAIL lines, the browser launch, watching a page for console
// errors and failed requests, counting a screenshot's colours.
let failed = 0;
export const ok = (m) => console.log(`ok   ${m}`);
export const fail = (m) => {
  console.log(`FAIL ${m}`);
  failed++;
};
export const failures = () => failed;

export function launch(puppeteer, chromium) {
  return puppeteer.launch({
    executablePath: chromium,
    headless: true,
    args: ["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--no-first-run"],
  });
}

// A new page of width x height watched for problems (pushed to problems), loaded from url.
export async function openPage(browser, url, label, problems, height = 1000) {
  const page = await browser.newPage();
  await page.setViewport({ width: 1400, height });
  watch(page, label, problems);
  await page.goto(url, { waitUntil: "load" });
  return page;
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
export async function colours(page, png) {
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

// A full-page screenshot to file, failed when blank (fewer than 200 distinct colours).
export async function screenshot(page, file) {
  const png = await page.screenshot({ path: file, fullPage: true });
  const n = await colours(page, png);
  if (n < 200) fail(`screenshot ${file} looks blank: ${n} distinct colours`);
  else ok(`screenshot ${file}: ${n} distinct colours`);
}

function readCsv(file) {
  const [head, ...rows] = fs.readFileSync(file, "utf8").trim().split("\n");
  const cols = head.split(",");
  return rows.map((r) => Object.fromEntries(r.split(",").map((v, i) => [cols[i], Number(v)])));
}

// The run page draws exactly the (frequency_hz, amplitude_m) points of csvFile (frf.csv), number
// for number (the API sends %.17g, which round-trips), each inside the plot's axes.
export async function drawsCsv(page, csvFile) {
  const drawn = await page.evaluate(() => window.rthsView.drawn.frf);
  const csv = readCsv(csvFile);
  if (drawn.length !== csv.length) fail(`page draws ${drawn.length} points, frf.csv has ${csv.length}`);
  else {
    const bad = csv.findIndex((r, i) => r.frequency_hz !== drawn[i][0] || r.amplitude_m !== drawn[i][1]);
    if (bad >= 0) fail(`point ${bad}: page (${drawn[bad]}) != frf.csv (${csv[bad].frequency_hz}, ${csv[bad].amplitude_m})`);
    else ok(`the page draws frf.csv's ${csv.length} points exactly`);
  }
  // several interface DoFs: every further DoF's points too (frf.csv's dof<d>_amplitude_m)
  const dofs = csv.length ? Object.keys(csv[0]).map((k) => /^dof(\d+)_amplitude_m$/.exec(k)).filter((m) => m && Number(m[1]) > 1) : [];
  const drawnDofs = await page.evaluate(() => window.rthsView.drawn.frfDofs || {});
  for (const m of dofs) {
    const d = m[1], got = drawnDofs[d] || [];
    const bad = csv.findIndex((r, i) => !got[i] || r.frequency_hz !== got[i][0] || r[m[0]] !== got[i][1]);
    if (got.length !== csv.length || bad >= 0) fail(`interface DoF ${d}: page draws ${got.length} points, frf.csv has ${csv.length}${bad >= 0 ? `; first difference at point ${bad}` : ""}`);
    else ok(`the page draws interface DoF ${d}'s ${csv.length} points exactly`);
  }
  // unstable points (frf.csv's stable = 0, converged) are drawn open
  const unstable = csv.filter((r) => r.converged === 1 && r.stable === 0).length * (1 + dofs.length);
  const drawnUnstable = await page.evaluate(() => window.rthsView.drawn.unstable);
  if (drawnUnstable !== unstable) fail(`the page draws ${drawnUnstable} points as unstable, frf.csv has ${unstable}`);
  else ok(`${unstable} unstable points drawn open, as frf.csv labels them`);
  const inside = await page.evaluate(() => window.rthsView.drawn.frfInside);
  if (inside !== csv.length) fail(`${csv.length - inside} of ${csv.length} points drawn outside the plot`);
  else ok("every point lies inside the plot's axes");
}

// Runs the test functions (each (browser) => problems[]) in one headless Chromium, reports the
// problems the pages had (or none, as label says), exits 1 on any failure.
export async function runInBrowser(puppeteer, chromium, outDir, label, tests) {
  fs.mkdirSync(outDir, { recursive: true });
  const browser = await launch(puppeteer, chromium);
  try {
    const problems = [];
    for (const t of tests) problems.push(...(await t(browser)));
    if (problems.length) problems.forEach((p) => fail(p));
    else ok(`${label}: no console error, page error or failed request`);
  } catch (e) {
    fail(`browser test: ${e.stack || e}`);
  } finally {
    await browser.close();
  }
  process.exit(failures() ? 1 : 0);
}

// Accepted points in a run folder's journal.jsonl now.
export function journalPoints(dir) {
  return fs.readFileSync(`${dir}/journal.jsonl`, "utf8").split("\n").filter((l) => l.includes('"point"')).length;
}
