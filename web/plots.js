// Shared by the run's page (app.js) and the controller process's page (controller.js): fetching,
// uPlot with labelled axes, fact lists. Classic script: its top-level names are the pages' globals.
"use strict";

const UM = 1e6; // m -> µm for display
const $ = (id) => document.getElementById(id);

async function getJSON(url) {
  const r = await fetch(url, { cache: "no-store" });
  const body = await r.json().catch(() => ({ error: `bad JSON from ${url}` }));
  if (!r.ok) throw new Error(body.error || `${url}: HTTP ${r.status}`);
  return body;
}

function plotSize(el, height) {
  return { width: Math.max(260, el.clientWidth - 4), height };
}

// Tick labels: plain numbers, no exponent below 1e5 (µm and Hz here), at most `digits` digits.
const fmtAxis = (digits) => (u, vals) =>
  vals.map((v) => {
    if (v == null) return "";
    if (v === 0) return "0";
    if (Math.abs(v) >= 1e5 || Math.abs(v) < 1e-3) return v.toExponential(1);
    return String(+v.toPrecision(digits));
  });

function nativePlot(el, height, xLabel, yLabel, series, extra = {}) {
  const opts = {
    ...plotSize(el, height),
    scales: { x: { time: false }, ...(extra.scales || {}) },
    axes: [
      { label: xLabel, values: extra.xValues || fmtAxis(6), ...(extra.xAxis || {}) },
      { label: yLabel, values: extra.yValues || fmtAxis(3), size: 64 },
      ...(extra.axes || []),
    ],
    legend: { live: false },
    cursor: { show: false },
    series: [{}].concat(series),
  };
  return new uPlot(opts, [[]].concat(series.map(() => [])), el);
}

function facts(el, rows) {
  el.innerHTML = "";
  for (const [k, v, cls] of rows) {
    const dt = document.createElement("dt");
    const dd = document.createElement("dd");
    dt.textContent = k;
    dd.textContent = v;
    if (cls) dd.className = cls;
    el.append(dt, dd);
  }
}

const sig = (x, d = 4) => (x == null || !isFinite(x) ? "–" : (+x).toPrecision(d));

function duration(s) {
  if (s == null || !isFinite(s)) return "–";
  if (s < 120) return `${s.toFixed(1)} s`;
  if (s < 7200) return `${(s / 60).toFixed(1)} min`;
  return `${(s / 3600).toFixed(2)} h`;
}


// Starts a page: its plots, a first load, then server-sent "change" events and resizing.
// page: {state, plots, makePlots, load, render, renderHeader, lost}: load(changed) fetches into
// state what changed (null: everything) and throws on failure; lost is what to say while the
// event stream is down. One load at a time; changes arriving meanwhile join the next one.
function startPage(page) {
  const { state } = page;
  if (window.rthsMissing) {
    state.error = window.rthsMissing;
    page.renderHeader();
    return;
  }
  let pending = Promise.resolve(), queued = null;
  const refresh = (changed) => {
    if (queued) {
      queued.changed = queued.changed && changed ? [...new Set([...queued.changed, ...changed])] : null;
      return pending;
    }
    const next = { changed };
    queued = next;
    pending = pending.then(async () => {
      queued = null;
      try {
        await page.load(next.changed);
      } catch (e) {
        state.error = `${e.message}`;
      }
      page.render();
    });
    return pending;
  };
  page.makePlots();
  refresh(null).then(() => {
    const es = new EventSource("api/events");
    es.addEventListener("change", (ev) => refresh(JSON.parse(ev.data).changed));
    es.onerror = () => {
      state.error = page.lost;
      page.renderHeader();
    };
    es.onopen = () => {
      if (state.error === page.lost) state.error = null;
      page.renderHeader();
    };
  });
  let width = window.innerWidth;
  window.addEventListener("resize", () => {
    if (window.innerWidth === width) return;
    width = window.innerWidth;
    for (const [id, u] of Object.entries(page.plots)) u.setSize(plotSize($(id), u.height));
  });
}
