// A run in progress, replayed from a finished one: node simulate_run.mjs FINISHED_DIR DEST_DIR
// START_POINTS INTERVAL_MS [--finish]. DEST gets FINISHED's config.yaml and truth.csv and the
// journal's header and first START_POINTS points at once (INTERVAL_MS 0: only that; a DEST that
// already holds a journal continues after its points), then one more point every INTERVAL_MS,
// with live.json replaced (temp + rename, as src/report/live.c does) from that point's measured
// coefficients. With --finish, frf.csv and summary.json are copied at the end, as the run writes
// them when it ends. Stands in for a paced `rths frf` until the run writes live.json itself.
import fs from "node:fs";
import path from "node:path";

const [src, dest, startText, intervalText, finish] = process.argv.slice(2);
const start = Number(startText), interval = Number(intervalText);
const lines = fs.readFileSync(path.join(src, "journal.jsonl"), "utf8").split("\n").filter(Boolean);
const header = lines[0], points = lines.slice(1);
fs.mkdirSync(dest, { recursive: true });
for (const f of ["config.yaml", "truth.csv"]) fs.copyFileSync(path.join(src, f), path.join(dest, f));
const journal = path.join(dest, "journal.jsonl");
let n = start;
if (fs.existsSync(journal)) n = fs.readFileSync(journal, "utf8").split("\n").filter((l) => l.includes('"point"')).length;
else fs.writeFileSync(journal, header + "\n" + points.slice(0, start).map((l) => l + "\n").join(""));
if (interval <= 0) process.exit(0);

function liveJson(p, n, history) {
  const f = p.frequency_hz, samples = 64;
  const time = [], phys = [], num = [];
  for (let i = 0; i < samples; i++) {
    const ph = (2 * Math.PI * i) / (samples - 1);
    let x = p.phys_a[0], y = p.num_a[0];
    for (let k = 1; k < p.phys_a.length; k++) {
      x += p.phys_a[k] * Math.cos(k * ph) + p.phys_b[k] * Math.sin(k * ph);
      y += p.num_a[k] * Math.cos(k * ph) + p.num_b[k] * Math.sin(k * ph);
    }
    time.push(i / (samples - 1) / f);
    phys.push(x);
    num.push(y);
  }
  return {
    format: 1, state: "running", point: n, points_accepted: n, iteration: history.length,
    evaluations_total: n * 2, frequency_hz: f, residual_m: p.residual_norm_m,
    residual_history_m: history, harmonics: p.harmonics,
    target: { a_m: p.target_a_m, b_m: p.target_b_m },
    physical: { a_m: p.phys_a, b_m: p.phys_b }, numerical: { a_m: p.num_a, b_m: p.num_b },
    period_s: 1 / f,
    trace: { source: "reconstructed from the latest period's harmonics", time_s: time, physical_m: phys, numerical_m: num },
    rig_time_s: p.rig_time_s * n, wall_time_s: n, unix_time_s: Date.now() / 1000,
    health: { fault: "none", fault_code: 0, remote: false, link_stats: false, overruns: null, worst_lateness_s: null },
  };
}

function replace(file, text) {
  fs.writeFileSync(file + ".tmp", text);
  fs.renameSync(file + ".tmp", file);
}

const timer = setInterval(() => {
  if (n >= points.length) {
    clearInterval(timer);
    if (finish === "--finish")
      for (const f of ["frf.csv", "summary.json"]) fs.copyFileSync(path.join(src, f), path.join(dest, f));
    return;
  }
  const p = JSON.parse(points[n]);
  const history = [p.residual_norm_m * 30, p.residual_norm_m * 4, p.residual_norm_m];
  replace(path.join(dest, "live.json"), JSON.stringify(liveJson(p, n, history), null, 1));
  fs.appendFileSync(journal, points[n] + "\n");
  n++;
}, interval);
