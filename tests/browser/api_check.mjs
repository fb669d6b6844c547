// The JSON API of `rths view` against the run folder's files: node api_check.mjs BASE_URL RUN_DIR
// CSV_PATH SOURCE [--uplot]. /api/points must equal CSV_PATH (frf.csv) number for number and name
// SOURCE (frf.csv or journal.jsonl) as where it came from; summary, truth and /run/ files must
// equal the folder's; paths leaving the folder are refused with 403 and never leak a byte of what
// they name; unknown paths get 404, other methods 405. Prints ok/FAIL lines, exits 1 on failure.
// BASE_URL may name a run of a campaign (http://HOST:PORT/runs/run_K/): the same checks under it.
// Plain Node (http, fs): no npm package needed.
import fs from "node:fs";
import http from "node:http";
import path from "node:path";

const [base, runDir, csvPath, source, uplotFlag] = process.argv.slice(2);
const url = new URL(base);
// a run of a campaign is served under /runs/run_K/: every path below is asked for under it
const prefix = url.pathname.replace(/\/+$/, "");
let failures = 0;
const ok = (m) => console.log(`ok   ${m}`);
const fail = (m) => {
  console.log(`FAIL ${m}`);
  failures++;
};

// A raw request: the path is sent exactly as given (no URL normalisation, unlike fetch).
function request(rawPath, method = "GET") {
  return new Promise((resolve, reject) => {
    const req = http.request({ host: url.hostname, port: url.port, path: prefix + rawPath, method }, (res) => {
      const chunks = [];
      res.on("data", (c) => chunks.push(c));
      res.on("end", () => resolve({ status: res.statusCode, type: res.headers["content-type"] || "", body: Buffer.concat(chunks) }));
    });
    req.on("error", reject);
    req.end();
  });
}

function csv(file) {
  const [head, ...rows] = fs.readFileSync(file, "utf8").trim().split("\n");
  return { columns: head.split(","), rows: rows.map((r) => r.split(",").map(Number)) };
}

// NaN in the CSV is null in JSON; everything else must be the same double.
const same = (a, j) => (Number.isNaN(a) ? j === null : j === a);

async function points() {
  const r = await request("/api/points");
  if (r.status !== 200) return fail(`/api/points: HTTP ${r.status}`);
  const api = JSON.parse(r.body);
  const ref = csv(csvPath);
  if (api.source !== source) fail(`/api/points source '${api.source}', expected '${source}'`);
  // journal.jsonl carries run.h's fixed columns; frf.csv adds the receptance, truth and
  // output-DoF columns after them, so a run in progress is compared on the journal's columns
  const want = source === "journal.jsonl" ? ref.columns.slice(0, api.columns.length) : ref.columns;
  if (JSON.stringify(api.columns) !== JSON.stringify(want)) fail(`/api/points columns ${api.columns} != ${want}`);
  if (api.points.length !== ref.rows.length) return fail(`/api/points: ${api.points.length} points, csv ${ref.rows.length}`);
  let compared = 0;
  for (let i = 0; i < ref.rows.length; i++)
    for (let c = 0; c < want.length; c++) {
      const j = api.points[i][ref.columns[c]];
      if (!same(ref.rows[i][c], j)) return fail(`/api/points point ${i} ${ref.columns[c]}: ${j} != ${ref.rows[i][c]}`);
      compared++;
    }
  ok(`/api/points (${source}) equals ${path.basename(csvPath)}: ${ref.rows.length} points, ${compared} numbers identical`);
}

async function files() {
  const summaryFile = path.join(runDir, "summary.json");
  const s = await request("/api/summary");
  if (fs.existsSync(summaryFile)) {
    if (s.status === 200 && JSON.stringify(JSON.parse(s.body)) === JSON.stringify(JSON.parse(fs.readFileSync(summaryFile))))
      ok("/api/summary equals summary.json");
    else fail(`/api/summary: HTTP ${s.status}`);
  } else if (s.status === 404 && /not ended/.test(JSON.parse(s.body).error)) ok(`/api/summary before the end: 404, ${JSON.parse(s.body).error}`);
  else fail(`/api/summary without summary.json: HTTP ${s.status}`);
  const liveFile = path.join(runDir, "live.json");
  const l = await request("/api/live");
  if (fs.existsSync(liveFile)) {
    if (l.status === 200 && JSON.stringify(JSON.parse(l.body)) === JSON.stringify(JSON.parse(fs.readFileSync(liveFile))))
      ok("/api/live equals live.json");
    else fail(`/api/live: HTTP ${l.status}`);
  } else if (l.status === 404 && JSON.parse(l.body).error) ok(`/api/live without live.json: 404 with a message`);
  else fail(`/api/live without live.json: HTTP ${l.status}`);
  const t = await request("/api/truth");
  const truth = csv(path.join(runDir, "truth.csv"));
  const tj = t.status === 200 ? JSON.parse(t.body) : {};
  const col = (name) => truth.rows.map((r) => r[truth.columns.indexOf(name)]);
  if (truth.columns.every((c) => JSON.stringify(tj[c]) === JSON.stringify(col(c)))) ok(`/api/truth equals truth.csv (${truth.rows.length} rows)`);
  else fail(`/api/truth differs from truth.csv (HTTP ${t.status})`);
  const f = await request("/run/truth.csv");
  if (f.status === 200 && f.body.equals(fs.readFileSync(path.join(runDir, "truth.csv")))) ok("/run/truth.csv serves the file byte for byte");
  else fail(`/run/truth.csv: HTTP ${f.status}`);
  const st = JSON.parse((await request("/api/status")).body);
  if (st.plan && st.plan.start_hz > 0 && st.files["journal.jsonl"]) ok(`/api/status: state ${st.state}, plan ${st.plan.start_hz}-${st.plan.end_hz} Hz`);
  else fail(`/api/status: ${JSON.stringify(st)}`);
}

async function refusals() {
  const secret = fs.readFileSync(path.join(runDir, "config.yaml"), "utf8").slice(0, 40);
  const traversals = [
    "/run/../config.yaml", "/run/..%2fconfig.yaml", "/run/%2e%2e/%2e%2e/etc/passwd", "/../../etc/passwd",
    "/assets/../run/config.yaml", "/run/%2E%2E%2Fsummary.json", "/run/..\\config.yaml", "/api/../run/config.yaml",
    "/run/outside_link",
  ];
  for (const p of traversals) {
    const r = await request(p);
    const body = r.body.toString();
    if (r.status === 403 && !body.includes("root:") && !body.includes(secret)) ok(`refused ${p}: 403`);
    else fail(`${p}: HTTP ${r.status}, ${body.slice(0, 80)}`);
  }
  for (const [p, want, type] of [["/nope", 404, "text/html"], ["/api/nope", 404, "application/json"], ["/run/no_such_file.csv", 404, "text/html"], ["/run/.hidden", 403, "text/html"]]) {
    const r = await request(p);
    if (r.status === want && r.type.startsWith(type)) ok(`${p}: ${want} ${type}`);
    else fail(`${p}: HTTP ${r.status} ${r.type}`);
  }
  const post = await request("/api/points", "POST");
  if (post.status === 405) ok("POST refused: 405");
  else fail(`POST: HTTP ${post.status}`);
}

async function page() {
  const r = await request("/");
  if (r.status === 200 && r.type.startsWith("text/html") && r.body.includes("uPlot.iife.min.js")) ok("/ serves the page");
  else fail(`/: HTTP ${r.status}`);
  const u = await request("/assets/uPlot.iife.min.js");
  const real = u.body.length > 20000 && u.body.includes("uPlot");
  if (u.status === 200 && (real || uplotFlag !== "--uplot")) ok(`uPlot served from the binary (${u.body.length} bytes)`);
  else fail(`/assets/uPlot.iife.min.js: HTTP ${u.status}, ${u.body.length} bytes`);
}

// The first server-sent event names what to fetch.
function firstEvent() {
  return new Promise((resolve) => {
    const req = http.get({ host: url.hostname, port: url.port, path: `${prefix}/api/events` }, (res) => {
      let text = "";
      res.on("data", (c) => {
        text += c;
        if (text.includes("event: change")) {
          req.destroy();
          resolve({ type: res.headers["content-type"], text });
        }
      });
    });
    req.on("error", () => {});
    setTimeout(() => {
      req.destroy();
      resolve({ type: "", text: "" });
    }, 5000);
  });
}

async function events() {
  const e = await firstEvent();
  if (e.type.startsWith("text/event-stream") && /"points"/.test(e.text)) ok("/api/events: a change event naming points");
  else fail(`/api/events: '${e.type}' '${e.text.slice(0, 100)}'`);
}

try {
  await points();
  await files();
  await refusals();
  await page();
  await events();
} catch (e) {
  fail(e.stack || String(e));
}
process.exit(failures ? 1 : 0);
