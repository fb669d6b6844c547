// rths live view: fetches the run's JSON (api/*, relative to the page: a run of a campaign is
// served under /runs/run_K/), redraws on server-sent "change" events.
// Amplitudes are shown in micrometres, times in seconds or milliseconds as labelled.
"use strict";

const COLORS = {
  truth: "#222222",
  point: "#1565c0",
  failed: "#c62828",
  fold: "#ef6c00",
  current: "#2e7d32",
  phys: "#1565c0",
  num: "#ef6c00",
  tol: "#888888",
};

// Further interface DoFs (frf.csv's dof<d>_* columns, d = 2, 3, 4); DoF 1 is COLORS.point.
const DOF_COLORS = ["#1565c0", "#6a1b9a", "#00838f", "#ad1457"];

const state = { status: null, points: [], truth: null, live: null, summary: null, error: null };
// What the page drew, for tests and the curious: window.rthsView.drawn.frf = [[f_hz, a_m], ...]
// (the first interface DoF); with several, drawn.frfDofs[d] = [[f_hz, dof<d>_amplitude_m], ...]
// for every DoF d >= 2; drawn.unstable = points drawn open as unstable.
window.rthsView = { state, drawn: { frf: [], frfDofs: {}, unstable: 0 }, renders: 0 };

// ---------- plots ----------

// A plot whose content is drawn by hand on uPlot's canvas (unsorted x: folds, Lissajous);
// uPlot gives axes, grid, legend and sizing. ranges() returns [[xmin, xmax], [ymin, ymax]].
function customPlot(el, height, xLabel, yLabel, legend, ranges, draw) {
  const series = [{}].concat(
    legend.map((s) => ({ label: s.label, stroke: s.color, dash: s.dash, width: 2, points: { show: false } })),
  );
  const opts = {
    ...plotSize(el, height),
    scales: { x: { time: false, auto: false }, y: { auto: false } },
    axes: [
      { label: xLabel, values: fmtAxis(6) },
      { label: yLabel, values: fmtAxis(4), size: 64 },
    ],
    legend: { live: false },
    cursor: { show: false },
    series,
    hooks: { draw: [(u) => draw(u, u.ctx)] },
  };
  const data = [[0, 1]].concat(legend.map(() => [null, null]));
  const u = new uPlot(opts, data, el);
  u.rthsRanges = ranges;
  return u;
}

// Sets a hand-drawn plot's axes to its content (which draws it again).
function rescale(u) {
  const [xr, yr] = u.rthsRanges();
  u.batch(() => {
    u.setScale("x", { min: xr[0], max: xr[1] });
    u.setScale("y", { min: yr[0], max: yr[1] });
  });
}

function padded(lo, hi, frac) {
  if (!isFinite(lo) || !isFinite(hi)) return [0, 1];
  if (hi === lo) return [lo - 1e-9 - Math.abs(lo) * 0.1, hi + 1e-9 + Math.abs(hi) * 0.1];
  const p = (hi - lo) * frac;
  return [lo - p, hi + p];
}

function line(u, ctx, xs, ys, color, width, dash) {
  ctx.save();
  ctx.strokeStyle = color;
  ctx.lineWidth = width * devicePixelRatio;
  ctx.setLineDash((dash || []).map((d) => d * devicePixelRatio));
  ctx.beginPath();
  let pen = false;
  for (let i = 0; i < xs.length; i++) {
    if (xs[i] == null || ys[i] == null) {
      pen = false;
      continue;
    }
    const x = u.valToPos(xs[i], "x", true), y = u.valToPos(ys[i], "y", true);
    if (pen) ctx.lineTo(x, y);
    else ctx.moveTo(x, y);
    pen = true;
  }
  ctx.stroke();
  ctx.restore();
}

function clipToPlot(u, ctx) {
  ctx.beginPath();
  ctx.rect(u.bbox.left, u.bbox.top, u.bbox.width, u.bbox.height);
  ctx.clip();
}

// ---------- the FRF ----------

// The interface DoFs beyond the first that the run reports (frf.csv's dof<d>_amplitude_m), sorted.
function extraDofs() {
  const first = state.points.find((p) => p.frequency_hz != null);
  if (!first) return [];
  return Object.keys(first)
    .map((k) => /^dof(\d+)_amplitude_m$/.exec(k))
    .filter((m) => m && Number(m[1]) > 1)
    .map((m) => Number(m[1]))
    .sort((a, b) => a - b);
}

function frfRanges() {
  const xs = [], ys = [];
  const dofs = extraDofs();
  for (const p of state.points) {
    if (p.frequency_hz != null) xs.push(p.frequency_hz);
    if (p.amplitude_m != null) ys.push(p.amplitude_m * UM);
    for (const d of dofs) if (p[`dof${d}_amplitude_m`] != null) ys.push(p[`dof${d}_amplitude_m`] * UM);
  }
  const plan = state.status && state.status.plan;
  if (plan) xs.push(plan.start_hz, plan.end_hz);
  if (!plan && state.truth) xs.push(...state.truth.frequency_hz);
  const xr = padded(Math.min(...xs), Math.max(...xs), 0.02);
  if (state.truth) {
    const t = state.truth;
    const curves = [t.amplitude_m].concat(dofs.map((d) => t[`dof${d}_amplitude_m`]).filter(Boolean));
    for (const c of curves)
      for (let i = 0; i < t.frequency_hz.length; i++)
        if (t.frequency_hz[i] >= xr[0] && t.frequency_hz[i] <= xr[1] && c[i] != null) ys.push(c[i] * UM);
  }
  const yr = ys.length ? [0, Math.max(...ys) * 1.08] : [0, 1];
  return [xr, yr];
}

// One interface DoF's points (amplitude column, its standard error column, colour): filled when
// accepted and stable, open when accepted but unstable (the run's fold-based label), open red
// when not converged; bars of +-3 standard errors.
function drawPoints(u, ctx, column, seColumn, color) {
  const drawn = [];
  let inside = 0, unstable = 0; // inside: marker centres within the plotting area
  const r = 4 * devicePixelRatio;
  for (const p of state.points) {
    if (p.frequency_hz == null || p[column] == null) continue;
    const x = u.valToPos(p.frequency_hz, "x", true);
    const y = u.valToPos(p[column] * UM, "y", true);
    const se = (p[seColumn] || 0) * 3 * UM;
    ctx.strokeStyle = ctx.fillStyle = p.converged ? color : COLORS.failed;
    ctx.lineWidth = 1.5 * devicePixelRatio;
    if (se > 0) {
      const y0 = u.valToPos(p[column] * UM - se, "y", true);
      const y1 = u.valToPos(p[column] * UM + se, "y", true);
      ctx.beginPath();
      ctx.moveTo(x, y0);
      ctx.lineTo(x, y1);
      ctx.moveTo(x - r, y0);
      ctx.lineTo(x + r, y0);
      ctx.moveTo(x - r, y1);
      ctx.lineTo(x + r, y1);
      ctx.stroke();
    }
    const isUnstable = p.converged && p.stable === 0;
    ctx.beginPath();
    ctx.arc(x, y, r, 0, 2 * Math.PI);
    if (p.converged && !isUnstable) ctx.fill();
    else {
      if (isUnstable) {
        ctx.fillStyle = "#ffffff";
        ctx.fill();
      }
      ctx.stroke();
    }
    unstable += isUnstable;
    drawn.push([p.frequency_hz, p[column]]);
    inside += x >= u.bbox.left && x <= u.bbox.left + u.bbox.width && y >= u.bbox.top && y <= u.bbox.top + u.bbox.height;
  }
  return { drawn, inside, unstable };
}

// With several interface DoFs: which colour is which DoF, in the plot's top right corner.
function dofKey(u, ctx, dofs) {
  const dpr = devicePixelRatio, lh = 16 * dpr;
  ctx.save();
  ctx.font = `${12 * dpr}px sans-serif`;
  ctx.textAlign = "right";
  ctx.textBaseline = "middle";
  const x = u.bbox.left + u.bbox.width - 10 * dpr;
  dofs.forEach((d, i) => {
    const y = u.bbox.top + (i + 1) * lh;
    ctx.fillStyle = DOF_COLORS[(d - 1) % 4];
    ctx.beginPath();
    ctx.arc(x - 4 * dpr, y, 4 * dpr, 0, 2 * Math.PI);
    ctx.fill();
    ctx.fillStyle = "#222222";
    ctx.fillText(`interface DoF ${d}`, x - 14 * dpr, y);
  });
  ctx.restore();
}

function drawFrf(u, ctx) {
  ctx.save();
  clipToPlot(u, ctx);
  const t = state.truth;
  if (t) {
    // stable parts solid, unstable parts dashed: split at every change of "stable"
    const st = t.stable || t.frequency_hz.map(() => 1);
    const stable = t.frequency_hz.map((f, i) => (st[i] || (i > 0 && st[i - 1]) ? f : null));
    const unstable = t.frequency_hz.map((f, i) => (!st[i] || (i > 0 && !st[i - 1]) ? f : null));
    const ys = t.amplitude_m.map((a) => (a == null ? null : a * UM));
    line(u, ctx, stable, ys, COLORS.truth, 2);
    line(u, ctx, unstable, ys, COLORS.truth, 1.5, [6, 4]);
  }
  const dofs = extraDofs();
  for (const d of dofs) {
    const c = t && t[`dof${d}_amplitude_m`];
    if (c) line(u, ctx, t.frequency_hz, c.map((a) => (a == null ? null : a * UM)), DOF_COLORS[(d - 1) % 4], 1.5);
  }
  const first = drawPoints(u, ctx, "amplitude_m", "amplitude_se_m", COLORS.point);
  window.rthsView.drawn.frfDofs = {};
  let unstable = first.unstable;
  for (const d of dofs) {
    const r = drawPoints(u, ctx, `dof${d}_amplitude_m`, `dof${d}_amplitude_se_m`, DOF_COLORS[(d - 1) % 4]);
    window.rthsView.drawn.frfDofs[d] = r.drawn;
    unstable += r.unstable;
  }
  if (dofs.length) dofKey(u, ctx, [1].concat(dofs));
  const drawn = first.drawn, inside = first.inside;
  window.rthsView.drawn.unstable = unstable;
  for (const f of folds()) {
    const x = u.valToPos(f.frequency_hz, "x", true), y = u.valToPos(f.amplitude_m * UM, "y", true);
    const s = 9 * devicePixelRatio;
    ctx.strokeStyle = COLORS.fold;
    ctx.lineWidth = 3 * devicePixelRatio;
    ctx.beginPath();
    ctx.moveTo(x - s, y - s);
    ctx.lineTo(x + s, y + s);
    ctx.moveTo(x - s, y + s);
    ctx.lineTo(x + s, y - s);
    ctx.stroke();
  }
  const live = state.live;
  if (live && live.state === "running" && !state.summary && live.frequency_hz) {
    const x = u.valToPos(live.frequency_hz, "x", true);
    line(u, ctx, [live.frequency_hz, live.frequency_hz], [u.scales.y.min, u.scales.y.max], COLORS.current, 1.5, [3, 3]);
    ctx.fillStyle = COLORS.current;
    ctx.fillText(" now", x, u.bbox.top + 14 * devicePixelRatio);
  }
  ctx.restore();
  window.rthsView.drawn.frf = drawn;
  window.rthsView.drawn.frfInside = inside;
}

// Folds: summary.json's located folds once the run has ended, else midway between the points
// a fold lies between (fold = 1 on the point before it).
function folds() {
  if (state.summary && Array.isArray(state.summary.folds)) return state.summary.folds;
  const out = [];
  const pts = state.points;
  for (let i = 0; i + 1 < pts.length; i++)
    if (pts[i].fold)
      out.push({
        frequency_hz: 0.5 * (pts[i].frequency_hz + pts[i + 1].frequency_hz),
        amplitude_m: 0.5 * (pts[i].amplitude_m + pts[i + 1].amplitude_m),
      });
  return out;
}

// ---------- the other panels ----------

// Equal spans on both axes (a match is the 45° diagonal), each centred on its own signal: the
// static displacement (a preload) would otherwise shrink the loop to a dot.
function lissajousRanges() {
  const l = state.live;
  if (!l || !l.trace || !l.trace.physical_m.length) return [[-1, 1], [-1, 1]];
  const p = l.trace.physical_m.filter((v) => v != null).map((v) => v * UM);
  const n = l.trace.numerical_m.filter((v) => v != null).map((v) => v * UM);
  const half = 0.55 * Math.max(Math.max(...p) - Math.min(...p), Math.max(...n) - Math.min(...n)) || 1;
  const pc = 0.5 * (Math.max(...p) + Math.min(...p)), nc = 0.5 * (Math.max(...n) + Math.min(...n));
  return [[pc - half, pc + half], [nc - half, nc + half]];
}

function drawLissajous(u, ctx) {
  const l = state.live;
  ctx.save();
  clipToPlot(u, ctx);
  const [xr, yr] = lissajousRanges();
  const lo = Math.min(xr[0], yr[0]), hi = Math.max(xr[1], yr[1]);
  line(u, ctx, [lo, hi], [lo, hi], COLORS.tol, 1, [4, 4]);
  if (l && l.trace) {
    const px = l.trace.physical_m.map((v) => (v == null ? null : v * UM));
    const ny = l.trace.numerical_m.map((v) => (v == null ? null : v * UM));
    line(u, ctx, px, ny, COLORS.point, 2);
  }
  ctx.restore();
}

function histogram() {
  const counts = new Map();
  for (const p of state.points) counts.set(p.evaluations, (counts.get(p.evaluations) || 0) + 1);
  const max = Math.max(0, ...counts.keys());
  const xs = [], ys = [];
  for (let k = 1; k <= max; k++) {
    xs.push(k);
    ys.push(counts.get(k) || 0);
  }
  return [xs, ys];
}

const plots = {};

function makePlots() {
  plots.frf = customPlot(
    $("frf"), 380, "Forcing frequency (Hz)", "Interface amplitude, fundamental (µm)",
    [
      { label: "true assembly, stable", color: COLORS.truth },
      { label: "true assembly, unstable", color: COLORS.truth, dash: [6, 4] },
      { label: "hybrid test, accepted points (bars: ±3 standard errors; open: unstable)", color: COLORS.point },
      { label: "not converged", color: COLORS.failed },
      { label: "fold", color: COLORS.fold },
      { label: "frequency being tested", color: COLORS.current, dash: [3, 3] },
    ],
    frfRanges, drawFrf,
  );
  plots.residual = nativePlot(
    $("residual"), 240, "Evaluation at this point", "Interface mismatch (m)",
    [
      { label: "residual of each evaluation", stroke: COLORS.point, width: 2, points: { show: true, size: 7 } },
      { label: "tolerance of the last accepted point", stroke: COLORS.tol, dash: [5, 4], width: 1.5, points: { show: false } },
    ],
    {
      scales: { y: { distr: 3 } },
      xValues: (u, v) => v.map((x) => (Number.isInteger(x) ? x : "")),
      yValues: (u, v) => v.map((x) => (x == null ? "" : x.toExponential(0))),
    },
  );
  plots.trace = nativePlot(
    $("trace"), 240, "Time within the period (ms)", "Displacement (µm)",
    [
      { label: "physical (rig)", stroke: COLORS.phys, width: 2, points: { show: false } },
      { label: "numerical (simulation)", stroke: COLORS.num, width: 2, dash: [6, 3], points: { show: false } },
    ],
  );
  plots.lissajous = customPlot(
    $("lissajous"), 240, "Physical interface displacement (µm)", "Numerical (µm)",
    [
      { label: "one period", color: COLORS.point },
      { label: "perfect match", color: COLORS.tol, dash: [4, 4] },
    ],
    lissajousRanges, drawLissajous,
  );
  plots.mismatch = nativePlot(
    $("mismatch"), 240, "Accepted point", "Interface mismatch (m)",
    [
      { label: "interface error, fundamental", stroke: COLORS.point, width: 1.5, points: { show: true, size: 5 } },
      { label: "tolerance", stroke: COLORS.tol, dash: [5, 4], width: 1.5, points: { show: false } },
      { label: "not converged", stroke: COLORS.failed, width: 0, points: { show: true, size: 8, fill: COLORS.failed } },
    ],
    {
      scales: { y: { distr: 3 } },
      xValues: (u, v) => v.map((x) => (Number.isInteger(x) ? x : "")),
      yValues: (u, v) => v.map((x) => (x == null ? "" : x.toExponential(0))),
    },
  );
  plots.histogram = nativePlot(
    $("histogram"), 240, "Evaluations (rig experiments) per point", "Points",
    [{ label: "accepted points", stroke: COLORS.point, fill: "rgba(21,101,192,0.35)", paths: uPlot.paths.bars({ size: [0.7, 60] }), points: { show: false } }],
    {
      scales: { x: { time: false, range: (u, lo, hi) => [lo - 0.6, hi + 0.6] }, y: { range: (u, lo, hi) => [0, Math.max(1, hi) * 1.1] } },
      xValues: (u, v) => v.map((x) => (Number.isInteger(x) ? x : "")),
      yValues: (u, v) => v.map((x) => (Number.isInteger(x) ? x : "")),
    },
  );
}

function renderPlots() {
  rescale(plots.frf);
  rescale(plots.lissajous);
  const l = state.live;
  if (l && l.residual_history_m && l.residual_history_m.length) {
    const h = l.residual_history_m;
    const last = state.points[state.points.length - 1];
    const tol = last && last.tolerance_m ? h.map(() => last.tolerance_m) : h.map(() => null);
    plots.residual.setData([h.map((_, i) => i + 1), h, tol]);
  }
  for (const id of ["residual", "trace", "lissajous"])
    $(id).classList.toggle("waiting", !(l && l.trace && l.trace.time_s.length));
  if (l && l.trace && l.trace.time_s.length)
    plots.trace.setData([
      l.trace.time_s.map((t) => t * 1e3),
      l.trace.physical_m.map((v) => (v == null ? null : v * UM)),
      l.trace.numerical_m.map((v) => (v == null ? null : v * UM)),
    ]);
  const pts = state.points.filter((p) => p.interface_error_m > 0);
  if (pts.length)
    plots.mismatch.setData([
      pts.map((p) => p.point),
      pts.map((p) => p.interface_error_m),
      pts.map((p) => (p.tolerance_m > 0 ? p.tolerance_m : null)),
      pts.map((p) => (p.converged ? null : p.interface_error_m)),
    ]);
  const [hx, hy] = histogram();
  if (hx.length) plots.histogram.setData([hx, hy]);
}

// ---------- facts ----------

// The accepted points' integrity (frf.csv's late_samples, clipped_demand_samples,
// saturated_sensor_samples of each point's accepted evaluation): any of them means the coupling
// did not hold for some samples the point rests on. Kept in window.rthsView.integrity for tests.
function integrityRow(pts) {
  const sum = (k) => pts.reduce((s, p) => s + (p[k] || 0), 0);
  const i = {
    late: sum("late_samples"),
    clipped: sum("clipped_demand_samples"),
    saturated: sum("saturated_sensor_samples"),
    points: pts.filter((p) => p.late_samples || p.clipped_demand_samples || p.saturated_sensor_samples).length,
  };
  window.rthsView.integrity = i;
  const any = i.late || i.clipped || i.saturated;
  return ["late / clipped / saturated samples", `${i.late} / ${i.clipped} / ${i.saturated}` + (any ? ` (${i.points} points)` : ""), any ? "bad" : "ok"];
}

function renderFacts() {
  const pts = state.points, plan = state.status && state.status.plan, l = state.live;
  const fs = pts.map((p) => p.frequency_hz).filter((f) => f != null);
  const lo = fs.length ? Math.min(...fs) : null, hi = fs.length ? Math.max(...fs) : null;
  const rig = pts.reduce((s, p) => s + (p.rig_time_s || 0), 0);
  const rigNow = l && l.rig_time_s != null ? Math.max(l.rig_time_s, rig) : rig;
  const converged = pts.filter((p) => p.converged).length;
  const evals = pts.reduce((s, p) => s + (p.evaluations || 0), 0);
  let fraction = null, left = null;
  if (plan && fs.length) {
    const span = Math.abs(plan.end_hz - plan.start_hz);
    const last = fs[fs.length - 1];
    const done = Math.min(span, Math.abs(last - plan.start_hz));
    fraction = state.summary ? 1 : span > 0 ? done / span : null;
    // rig time per Hz so far, times what is left: rough on an arclength run (folds go back)
    if (!state.summary && done > 0) left = (rigNow / done) * (span - done);
  }
  facts($("progress"), [
    ["accepted points", `${pts.length} (${converged} converged)`],
    ["frequency covered", fs.length ? `${sig(lo, 6)} – ${sig(hi, 6)} Hz` : "–"],
    ["planned range", plan ? `${plan.start_hz} → ${plan.end_hz} Hz (${plan.method})` : "–"],
    ["evaluations", l ? `${Math.max(evals, l.evaluations_total)}` : `${evals}`],
    ["rig time", duration(rigNow)],
    ["estimated rig time left", state.summary ? "done" : duration(left)],
    ["now", l && !state.summary ? `point ${l.point}, ${sig(l.frequency_hz, 6)} Hz, evaluation ${l.iteration}` : "–"],
  ]);
  $("bar-fill").style.width = `${Math.round(100 * (fraction || 0))}%`;
  const h = l && l.health;
  const age = l && l.unix_time_s ? Date.now() / 1000 - l.unix_time_s : null;
  const rows = [
    ["rig fault", h ? h.fault : "–", h ? (h.fault_code ? "bad" : "ok") : null],
    ["points not converged", `${pts.length - converged}`, pts.length - converged ? "warn" : "ok"],
    ["largest interface error", `${sig(Math.max(0, ...pts.map((p) => p.interface_error_m || 0)), 3)} m`],
    integrityRow(pts),
    ["live.json", l ? (state.summary || l.state === "ended" ? "final" : `updated ${duration(age)} ago`) : "not written by this run", age > 60 && !state.summary && l && l.state !== "ended" ? "warn" : null],
  ];
  if (h && h.link_stats) {
    rows.push(["controller overruns", `${h.overruns}`, h.overruns ? "warn" : "ok"]);
    rows.push(["worst lateness", `${sig(h.worst_lateness_s * 1e6, 3)} µs`]);
  }
  if (state.summary) {
    rows.push(["stopped", state.summary.stop_reason || "–"]);
    if (state.summary.max_relative_error_vs_truth != null)
      rows.push(["max deviation from truth", `${sig(100 * state.summary.max_relative_error_vs_truth, 3)} %`]);
  }
  // a live process's own snapshot (the controller's page): its scalar fields as they come
  const proc = state.status && state.status.process;
  if (proc)
    for (const [k, v] of Object.entries(proc))
      if (v === null || typeof v !== "object") rows.push([k.replace(/_/g, " "), String(v)]);
  facts($("health"), rows);
}

function renderHeader() {
  const s = state.status;
  $("run").textContent = s && s.run_dir ? s.run_dir : "";
  // a run of a campaign (rths view CAMPAIGN_DIR): the way back to the campaign's page
  $("campaign-link").hidden = !(s && s.campaign_page);
  const badge = $("state");
  const st = state.error ? "problem" : s ? s.state : "connecting";
  badge.textContent = st === "gone" ? "run folder gone" : st;
  badge.className = `badge ${st === "gone" ? "problem" : st}`;
  const p = $("problem");
  p.hidden = !state.error;
  p.textContent = state.error || "";
}

function render() {
  renderHeader();
  renderFacts();
  renderPlots();
  window.rthsView.renders++;
}

// ---------- data ----------

// Fetches what changed (only files the folder holds, so a finished run asks for no live.json
// and the browser logs no 404).
async function load(changed) {
  state.status = await getJSON("api/status");
  const files = state.status.files || {};
  const want = (k) => state.status.run_dir && (!changed || changed.includes(k));
  if (want("points")) state.points = (await getJSON("api/points")).points;
  if (want("truth") && files["truth.csv"]) state.truth = await getJSON("api/truth");
  if (want("live")) state.live = files["live.json"] ? await getJSON("api/live") : null;
  if (want("summary")) state.summary = files["summary.json"] ? await getJSON("api/summary") : null;
  state.error = state.status.state === "gone" ? `The run folder ${state.status.run_dir} is gone.` : null;
}

startPage({
  state,
  plots,
  makePlots,
  load,
  render,
  renderHeader,
  lost: "Lost the connection to rths view; retrying.",
});
