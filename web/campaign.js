// rths view of a campaign folder (rths campaign --out DIR, docs/campaign.md): campaign.csv as a
// sortable table whose runs link to their own pages (/runs/run_K/), and any result column
// plotted against a grid column; redrawn on server-sent "change" events (after every run).
"use strict";

const GROUP_COLORS = ["#1565c0", "#ef6c00", "#2e7d32", "#6a1b9a", "#c62828", "#00838f", "#ad1457", "#5d4037"];

const state = {
  status: null,
  table: null, // /api/campaign
  error: null,
  sort: { column: "run", up: true },
  x: null, // chosen columns (kept across reloads)
  y: null,
  group: null,
};
// What the page drew, for tests: drawn.points = [[run, x, y], ...] (every finished run with both
// values), drawn.rows = the run names in table order, drawn.links = runs shown as links.
window.rthsCampaign = { state, drawn: { points: [], rows: [], links: [] }, renders: 0 };

const plots = {};

// ---------- values ----------

const isNum = (v) => typeof v === "number" && isFinite(v);

// A grid column whose values are not all numbers (e.g. controller.scheme): its distinct values in
// order of first appearance, plotted at 0, 1, 2, ...
function categories(column) {
  const runs = state.table ? state.table.runs : [];
  const values = runs.map((r) => r[column]).filter((v) => v != null);
  if (values.every(isNum)) return null;
  return [...new Set(values.map(String))];
}

function position(v, cats) {
  if (v == null) return null;
  if (!cats) return isNum(v) ? v : null;
  const i = cats.indexOf(String(v));
  return i < 0 ? null : i;
}

function cell(v) {
  if (v == null) return "";
  if (isNum(v)) return Number.isInteger(v) ? String(v) : String(+v.toPrecision(6));
  return String(v);
}

// ---------- plot ----------

function makePlots() {
  const el = $("scatter");
  const opts = {
    ...plotSize(el, 320),
    scales: { x: { time: false, auto: false }, y: { auto: false } },
    axes: [
      { label: "", values: (u, vals) => xTicks(vals) },
      { label: "", values: fmtAxis(4), size: 70 },
    ],
    legend: { show: false },
    cursor: { show: false },
    series: [{}, { stroke: "transparent" }],
    hooks: { draw: [(u) => drawScatter(u, u.ctx)] },
  };
  plots.scatter = new uPlot(opts, [[0, 1], [null, null]], el);
}

function xTicks(vals) {
  const cats = state.x ? categories(state.x) : null;
  if (!cats) return fmtAxis(6)(null, vals);
  return vals.map((v) => (Number.isInteger(v) && v >= 0 && v < cats.length ? cats[v] : ""));
}

// Points and mean lines per group: [{label, color, points: [[x, y, run]], means: [[x, y]]}].
function scatterData() {
  const t = state.table;
  if (!t || !state.x || !state.y) return [];
  const cx = categories(state.x), cy = categories(state.y);
  const groups = new Map();
  for (const r of t.runs) {
    const x = position(r[state.x], cx), y = position(r[state.y], cy);
    if (x == null || y == null) continue;
    const key = state.group ? cell(r[state.group]) : "";
    if (!groups.has(key)) groups.set(key, []);
    groups.get(key).push([x, y, r.run]);
  }
  return [...groups.entries()].map(([label, points], i) => {
    const byX = new Map();
    for (const [x, y] of points) byX.set(x, (byX.get(x) || []).concat([y]));
    const means = [...byX.entries()]
      .map(([x, ys]) => [x, ys.reduce((a, b) => a + b, 0) / ys.length])
      .sort((a, b) => a[0] - b[0]);
    return { label, color: GROUP_COLORS[i % GROUP_COLORS.length], points, means };
  });
}

function padded(lo, hi) {
  if (!isFinite(lo) || !isFinite(hi)) return [0, 1];
  if (hi === lo) {
    const d = Math.abs(lo) * 0.1 || 1;
    return [lo - d, hi + d];
  }
  const p = (hi - lo) * 0.06;
  return [lo - p, hi + p];
}

function drawScatter(u, ctx) {
  const groups = u.rthsGroups || [];
  const dpr = devicePixelRatio;
  ctx.save();
  for (const g of groups) {
    ctx.strokeStyle = g.color;
    ctx.fillStyle = g.color;
    ctx.lineWidth = 1.5 * dpr;
    ctx.beginPath();
    g.means.forEach(([x, y], i) => {
      const px = u.valToPos(x, "x", true), py = u.valToPos(y, "y", true);
      if (i) ctx.lineTo(px, py);
      else ctx.moveTo(px, py);
    });
    ctx.stroke();
    for (const [x, y] of g.points) {
      ctx.beginPath();
      ctx.arc(u.valToPos(x, "x", true), u.valToPos(y, "y", true), 4 * dpr, 0, 2 * Math.PI);
      ctx.fill();
    }
  }
  // the legend: one entry per group, top left inside the plot area
  if (groups.length > 1 || (groups.length === 1 && groups[0].label)) {
    ctx.font = `${12 * dpr}px sans-serif`;
    let y = u.bbox.top + 14 * dpr;
    for (const g of groups) {
      ctx.fillStyle = g.color;
      ctx.fillRect(u.bbox.left + 8 * dpr, y - 8 * dpr, 10 * dpr, 10 * dpr);
      ctx.fillStyle = "#1d2733";
      ctx.fillText(`${state.group} = ${g.label}`, u.bbox.left + 24 * dpr, y + 1 * dpr);
      y += 16 * dpr;
    }
  }
  ctx.restore();
}

function renderPlot() {
  const u = plots.scatter;
  const groups = scatterData();
  u.rthsGroups = groups;
  const pts = groups.flatMap((g) => g.points);
  window.rthsCampaign.drawn.points = pts.map(([x, y, run]) => [run, x, y]);
  const xs = pts.map((p) => p[0]), ys = pts.map((p) => p[1]);
  const [x0, x1] = padded(Math.min(...xs), Math.max(...xs));
  const [y0, y1] = padded(Math.min(...ys), Math.max(...ys));
  u.axes[0].label = state.x || "";
  u.axes[1].label = state.y || "";
  u.batch(() => {
    u.setScale("x", { min: x0, max: x1 });
    u.setScale("y", { min: y0, max: y1 });
  });
  u.redraw(false, true); // the axis labels changed
}

// ---------- controls ----------

function fillSelect(el, options, chosen, none) {
  const want = JSON.stringify([none, options]);
  if (el.dataset.options !== want) {
    el.innerHTML = "";
    if (none) el.add(new Option(none, ""));
    for (const o of options) el.add(new Option(o, o));
    el.dataset.options = want;
  }
  el.value = chosen || "";
}

function chooseDefaults() {
  const t = state.table;
  const grid = t.grid || [], outputs = (t.outputs || []).filter((c) => c !== "exit_status");
  const xs = grid.concat(["seed"].filter((c) => !grid.includes(c) && t.columns.includes(c)));
  const ys = outputs.concat(grid);
  if (!xs.includes(state.x)) state.x = xs[0] || null;
  if (!ys.includes(state.y))
    state.y = outputs.includes("max_relative_error_vs_truth") ? "max_relative_error_vs_truth" : ys[0] || null;
  if (state.group && !xs.includes(state.group)) state.group = null;
  if (!state.defaulted) {
    // at first: one curve per value of the second grid key, when there is one
    state.group = grid.length > 1 && grid[1] !== state.x ? grid[1] : null;
    state.defaulted = true;
  }
  fillSelect($("x"), xs, state.x);
  fillSelect($("y"), ys, state.y);
  fillSelect($("group"), xs.filter((c) => c !== state.x), state.group, "(none)");
}

function bindControls() {
  $("x").addEventListener("change", (e) => {
    state.x = e.target.value;
    if (state.group === state.x) state.group = null;
    render();
  });
  $("y").addEventListener("change", (e) => {
    state.y = e.target.value;
    render();
  });
  $("group").addEventListener("change", (e) => {
    state.group = e.target.value || null;
    render();
  });
}

// ---------- table ----------

function sortedRuns() {
  const t = state.table;
  const order = t.runs.map((r, i) => i);
  const { column, up } = state.sort;
  const cmp = (a, b) => {
    const va = t.runs[a][column], vb = t.runs[b][column];
    if (va == null && vb == null) return a - b;
    if (va == null) return 1; // unfinished last, whichever way
    if (vb == null) return -1;
    const d = isNum(va) && isNum(vb) ? va - vb : String(va).localeCompare(String(vb));
    return (up ? d : -d) || a - b;
  };
  return order.sort(cmp);
}

function renderTable() {
  const t = state.table;
  const table = $("runs");
  table.innerHTML = "";
  const head = table.createTHead().insertRow();
  for (const c of t.columns) {
    const th = document.createElement("th");
    th.textContent = c;
    th.dataset.column = c;
    if ((t.grid || []).includes(c)) th.classList.add("grid");
    if (state.sort.column === c) th.classList.add(state.sort.up ? "sorted-up" : "sorted-down");
    th.addEventListener("click", () => {
      state.sort = { column: c, up: state.sort.column === c ? !state.sort.up : true };
      renderTable();
    });
    head.append(th);
  }
  const body = table.createTBody();
  const rows = [], links = [];
  for (const i of sortedRuns()) {
    const r = t.runs[i];
    const tr = body.insertRow();
    if (r.exit_status == null) tr.className = "pending";
    else if (r.exit_status !== 0) tr.className = "failed";
    for (const c of t.columns) {
      const td = tr.insertCell();
      if (c === "run" && t.run_folders[i]) {
        const a = document.createElement("a");
        a.href = `/runs/${encodeURIComponent(r.run)}/`;
        a.textContent = r.run;
        td.append(a);
        links.push(r.run);
      } else {
        td.textContent = cell(r[c]);
        if (isNum(r[c])) td.title = String(r[c]);
      }
    }
    rows.push(r.run);
  }
  window.rthsCampaign.drawn.rows = rows;
  window.rthsCampaign.drawn.links = links;
}

// ---------- page ----------

function renderFacts() {
  const t = state.table, c = state.status && state.status.campaign;
  const total = t ? t.total : 0, finished = t ? t.finished : 0, failed = t ? t.failed : 0;
  facts($("progress"), [
    ["configuration", c && c.config ? c.config : "–"],
    ["runs", `${total}`],
    ["finished", `${finished}`],
    ["failed", `${failed}`, failed ? "bad" : "ok"],
    ["grid", t && t.grid.length ? t.grid.join(", ") : "–"],
  ]);
  $("bar-fill").style.width = `${total ? Math.round((100 * finished) / total) : 0}%`;
}

function renderHeader() {
  const s = state.status;
  $("run").textContent = s && s.run_dir ? s.run_dir : "";
  const badge = $("state");
  const st = state.error ? "problem" : s ? s.state : "connecting";
  badge.textContent = st === "gone" ? "campaign folder gone" : st;
  badge.className = `badge ${st === "gone" ? "problem" : st}`;
  const p = $("problem");
  p.hidden = !state.error;
  p.textContent = state.error || "";
}

function render() {
  renderHeader();
  if (state.table) {
    chooseDefaults();
    renderFacts();
    renderTable();
    renderPlot();
  }
  window.rthsCampaign.renders++;
}

async function load(changed) {
  state.status = await getJSON("api/status");
  if (state.status.state === "gone") {
    state.error = `The campaign folder ${state.status.run_dir} is gone.`;
    return;
  }
  if (!changed || changed.includes("campaign") || !state.table) state.table = await getJSON("api/campaign");
  state.error = null;
}

bindControls();
startPage({
  state,
  plots,
  makePlots,
  load,
  render,
  renderHeader,
  lost: "Lost the connection to rths view; retrying.",
});
