// rths controller live view: fetches /api/process (the loop's published state, the last second of
// decimated interface signals, the lateness histogram), redraws on server-sent "change" events.
// Displacements in micrometres, force in newtons, times as labelled.
"use strict";

const COLORS = { phys: "#1565c0", num: "#ef6c00", target: "#555555", force: "#2e7d32", bars: "#1565c0" };

const state = { process: null, error: null };
// What the page drew, for tests: the scope's sample count and latest controller time, the
// histogram's counts.
window.rthsView = { state, drawn: { scope: 0, scopeLastTime: null, lateness: [] }, renders: 0 };

const plots = {};

function microseconds(s) {
  if (s >= 1e-3) return `${+(s * 1e3).toPrecision(3)} ms`;
  return `${+(s * 1e6).toPrecision(3)} µs`;
}

function makePlots() {
  plots.scope = nativePlot(
    $("scope"), 360, "Controller time (s)", "Interface displacement (µm)",
    [
      { label: "physical (measured)", stroke: COLORS.phys, width: 2, points: { show: false } },
      { label: "numerical (simulation)", stroke: COLORS.num, width: 2, dash: [6, 3], points: { show: false } },
      { label: "target", stroke: COLORS.target, width: 1.5, dash: [2, 3], points: { show: false } },
      { label: "interface force (N, right axis)", stroke: COLORS.force, width: 1, scale: "force", points: { show: false } },
    ],
    {
      scales: { force: { auto: true } },
      axes: [{ scale: "force", side: 1, label: "Interface force (N)", values: fmtAxis(3), size: 64, grid: { show: false } }],
    },
  );
  plots.lateness = nativePlot(
    $("lateness"), 260, "Lateness of the wake-up (bin from its lower edge)", "Samples (log scale)",
    [{ label: "loop wake-ups", stroke: COLORS.bars, fill: "rgba(21,101,192,0.35)", paths: uPlot.paths.bars({ size: [0.8, 80] }), points: { show: false } }],
    {
      scales: { x: { time: false, range: (u, lo, hi) => [lo - 0.6, hi + 0.6] }, y: { distr: 3, range: (u, lo, hi) => [0.5, Math.max(10, hi) * 2] } },
      xAxis: { splits: (u) => (u.data[0] || []).slice() },
      xValues: (u, v) => v.map((i) => latenessLabel(i)),
      yValues: (u, v) => v.map((y) => (y == null ? "" : y >= 1e4 ? y.toExponential(0) : String(y))),
    },
  );
}

function latenessLabel(i) {
  const p = state.process;
  if (!p || !Number.isInteger(i) || i < 0 || i >= p.lateness.edges_s.length) return "";
  const e = p.lateness.edges_s;
  if (i === e.length - 1) return `≥${microseconds(e[i])}`;
  return e[i] === 0 ? "0" : microseconds(e[i]);
}

function renderScope() {
  const sc = state.process.scope;
  const n = sc.time_s.length;
  $("scope-title").textContent = `Oscilloscope: interface signals, last ${n ? (sc.time_s[n - 1] - sc.time_s[0]).toFixed(2) : 0} s (every ${sc.decimation}th loop sample, ${(1 / sc.sample_period_s).toFixed(0)} Hz)`;
  const um = (a) => a.map((v) => (v == null ? null : v * UM));
  if (n) plots.scope.setData([sc.time_s, um(sc.x_phys_m), um(sc.x_num_m), um(sc.target_m), sc.force_n]);
  window.rthsView.drawn.scope = n;
  window.rthsView.drawn.scopeLastTime = n ? sc.time_s[n - 1] : null;
}

function renderLateness() {
  const l = state.process.lateness;
  const xs = l.counts.map((_, i) => i);
  plots.lateness.setData([xs, l.counts.map((c) => (c > 0 ? c : null))]);
  window.rthsView.drawn.lateness = l.counts.slice();
}

function renderFacts() {
  const s = state.process.state;
  const sc = state.process.scope;
  let peak = 0;
  for (const v of sc.x_phys_m) if (v != null) peak = Math.max(peak, Math.abs(v));
  facts($("safety"), [
    ["armed", s.armed ? "yes" : "no", s.armed ? "ok" : null],
    ["limit state", s.fault === "no" ? "none latched" : `${s.fault} latched`, s.fault === "no" ? "ok" : "bad"],
    ["peak displacement (window)", `${sig(peak * UM, 3)} µm = ${sig((100 * peak) / s.displacement_limit_m, 2)} % of the limit`],
    ["last disarm", s.last_disarm],
    ["watchdog", s.watchdog, s.watchdog.startsWith("tripped") ? "bad" : s.watchdog.includes("slow") ? "warn" : "ok"],
    ["host", s.host_connected ? `connected, silent ${sig(s.host_silence_s, 2)} s of ${s.watchdog_s} s` : "none connected"],
    ["forcing", `${sig(s.forcing_hz, 6)} Hz, ${sig(s.forcing_amplitude_n, 4)} N`],
    ["controller time", duration(s.controller_time_s)],
  ]);
  $("bar-fill").style.width = `${Math.min(100, Math.round((100 * s.host_silence_s) / s.watchdog_s))}%`;
  facts($("timing"), [
    ["samples", `${s.samples}`],
    ["overruns", `${s.overruns}`, s.overruns ? "warn" : "ok"],
    ["resyncs", `${s.resyncs}`, s.resyncs ? "warn" : "ok"],
    ["lateness p50 / p99", `${microseconds(s.lateness_p50_s)} / ${microseconds(s.lateness_p99_s)}`],
    ["worst lateness", microseconds(s.worst_lateness_s), s.worst_lateness_s > s.sample_period_s ? "warn" : null],
    ["step cost mean / max", `${microseconds(s.step_mean_s)} / ${microseconds(s.step_max_s)}`],
    ["sample period", microseconds(s.sample_period_s)],
    ["real-time features", s.realtime || "none (best effort)"],
    ["periods the host missed", `${s.periods_dropped}`, s.periods_dropped ? "warn" : null],
    ["scope samples dropped", `${s.scope_dropped}`],
  ]);
}

function renderHeader() {
  const p = state.process;
  const s = p && p.state;
  $("run").textContent = s ? `t = ${s.controller_time_s.toFixed(3)} s, forcing ${sig(s.forcing_hz, 5)} Hz` : "";
  const badge = $("state");
  const st = state.error ? "problem" : !s ? "connecting" : s.fault !== "no" ? "fault" : s.armed ? "armed" : "disarmed";
  badge.textContent = st === "fault" ? `${s.fault} fault` : st;
  badge.className = `badge ${st === "fault" ? "problem" : st}`;
  const el = $("problem");
  el.hidden = !state.error;
  el.textContent = state.error || "";
}

function render() {
  renderHeader();
  if (state.process) {
    renderScope();
    renderLateness();
    renderFacts();
  }
  window.rthsView.renders++;
}

async function load() {
  state.process = await getJSON("/api/process");
  state.error = null;
}

startPage({
  state,
  plots,
  makePlots,
  load,
  render,
  renderHeader,
  lost: "Lost the connection to the controller; retrying.",
});
