// roverops console: the sol timeline review. A sol's commands, NATE modes, Attitude
// Quality Flags and events as lanes over LMST, with the estimate's errors and the HGA
// pointing margin plotted underneath (uPlot, vendored in /static/vendor/uplot) on the same
// LMST axis, and the sol's telemetry as a CSV download.
// Wrapped in a function: console.js already owns the global names ($, state, api, ...).
(function () {
  "use strict";

  const byId = (id) => document.getElementById(id);
  const MAX_POINTS = 2000; // the plots ask the server for at most about this many frames
  const MIN_SPAN_H = 1 / 60; // a sol with a single frame still gets a minute of axis
  const TICK_MINUTES = [1, 2, 5, 10, 15, 20, 30, 60, 120, 180, 240, 360, 720];
  const TICK_SPACE_PX = 72; // at least this far between LMST labels
  // The plots' y axis is this wide and they have no left padding, so their plotting area
  // starts where the lanes' tracks start (the lane label column has the same width).
  const GUTTER_PX = 72; // = --tl-gutter in console.css
  const RIGHT_PAD_PX = 16;
  const PLOT_HEIGHT_PX = 150;
  const X_AXIS_PX = 30; // room for the hh:mm labels under a plot (uPlot's default is 50)
  const PALETTE = { ink: "#dde6ee", dim: "#8a99a8", line: "#2a3642", zero: "#ff6b6b" };

  // span: the sol's [first, last] LMST hours, the x range of the lanes and the plots
  const view = { rover: null, span: null, plots: [], generation: 0 };

  // ---- time formatting --------------------------------------------------------------

  function hhmm(lmst_h) {
    const minutes = Math.round(lmst_h * 60);
    const h = Math.floor(minutes / 60) % 24;
    return `${String(h).padStart(2, "0")}:${String(minutes % 60).padStart(2, "0")}`;
  }

  function hhmmss(lmst_h) {
    const seconds = Math.round(lmst_h * 3600);
    const h = Math.floor(seconds / 3600) % 24;
    const m = Math.floor((seconds % 3600) / 60);
    return `${String(h).padStart(2, "0")}:${String(m).padStart(2, "0")}:${String(seconds % 60).padStart(2, "0")}`;
  }

  // The tick step the plots' x axis takes too (uPlot: the smallest increment that leaves
  // TICK_SPACE_PX between ticks), so the lanes' ticks line up with the plots' grid.
  function tickMinutes(span_h, width_px) {
    return TICK_MINUTES.find((m) => (width_px * m) / (span_h * 60) >= TICK_SPACE_PX) || TICK_MINUTES.at(-1);
  }

  // uPlot rejects increments with more than ~16 decimals (1/60 h has 18): round them.
  const TICK_INCRS_H = TICK_MINUTES.map((m) => Number((m / 60).toFixed(12)));

  // ---- data -------------------------------------------------------------------------

  async function getJson(path) {
    const response = await fetch(path);
    if (!response.ok) {
      let detail = response.statusText;
      try { detail = (await response.json()).detail; } catch (_) { /* not JSON */ }
      throw new Error(`${path}: ${response.status} ${typeof detail === "string" ? detail : JSON.stringify(detail)}`);
    }
    return response.json();
  }

  function telemetryPath(rover, timeline) {
    const t0 = timeline.start.t_s, t1 = timeline.end.t_s;
    const every = Math.min(86400, Math.max(0, (t1 - t0) / MAX_POINTS));
    const query = new URLSearchParams({
      from: String(t0), to: String(t1), every: every.toFixed(3), limit: String(2 * MAX_POINTS),
    });
    return `/api/rovers/${encodeURIComponent(rover)}/telemetry?${query}`;
  }

  function csvPath(rover, sol) {
    return `/api/rovers/${encodeURIComponent(rover)}/sols/${sol}/telemetry.csv`;
  }

  // ---- the sol picker ---------------------------------------------------------------

  async function fillSols({ followLatest }) {
    const picker = byId("timeline-sol");
    const sols = await getJson(`/api/rovers/${encodeURIComponent(view.rover)}/sols`);
    const previous = Number(picker.value);
    const wasLatest = picker.options.length > 0 && picker.selectedIndex === picker.options.length - 1;
    picker.replaceChildren(...sols.map((s) => new Option(`Sol ${s}`, String(s))));
    if (!sols.length) return null;
    const keep = !followLatest && !wasLatest && sols.includes(previous);
    picker.value = String(keep ? previous : sols.at(-1));
    return Number(picker.value);
  }

  async function reload({ followLatest }) {
    const generation = ++view.generation; // a later reload makes this one's answers stale
    const rover = byId("rover").value;
    if (!rover) return;
    view.rover = rover;
    setStatus("Loading…");
    try {
      const sol = await fillSols({ followLatest });
      if (generation !== view.generation) return;
      if (sol === null) { showEmpty(`No telemetry yet for ${rover}.`); return; }
      await loadSol(sol, generation);
    } catch (err) {
      if (generation === view.generation) setStatus(`Could not load the timeline: ${err.message}`, true);
    }
  }

  async function pickSol() {
    const generation = ++view.generation;
    try {
      await loadSol(Number(byId("timeline-sol").value), generation);
    } catch (err) {
      if (generation === view.generation) setStatus(`Could not load the timeline: ${err.message}`, true);
    }
  }

  async function loadSol(sol, generation) {
    setStatus("Loading…");
    const rover = view.rover;
    const timeline = await getJson(`/api/rovers/${encodeURIComponent(rover)}/sols/${sol}/timeline`);
    const frames = await getJson(telemetryPath(rover, timeline));
    if (generation !== view.generation) return;
    const x0 = timeline.start.lmst_h;
    view.span = [x0, Math.max(timeline.end.lmst_h, x0 + MIN_SPAN_H)];
    view.start = timeline.start;
    const link = byId("timeline-csv");
    link.href = csvPath(rover, sol);
    link.setAttribute("download", `${rover}_sol${sol}.csv`);
    link.removeAttribute("aria-disabled");
    byId("timeline-panel").classList.remove("empty");
    showSummary(timeline);
    drawLanes(timeline);
    drawPlots(frames);
    setStatus(`${frames.length} frames plotted`);
  }

  function showEmpty(message) {
    view.span = null;
    const link = byId("timeline-csv");
    link.removeAttribute("href");
    link.setAttribute("aria-disabled", "true");
    byId("timeline-panel").classList.add("empty");
    byId("timeline-summary").replaceChildren();
    for (const id of ["lane-commands", "lane-nate", "lane-aqf", "lane-events", "lane-vo", "lane-alarms", "lane-axis"]) {
      byId(id).replaceChildren();
    }
    destroyPlots();
    setStatus(message);
  }

  function setStatus(text, bad = false) {
    const status = byId("timeline-status");
    status.textContent = text;
    status.className = bad ? "timeline-status bad" : "timeline-status";
  }

  // ---- summary ----------------------------------------------------------------------

  function fixed(value, digits, unit) {
    return value === null || value === undefined ? "—" : `${value.toFixed(digits)}${unit}`;
  }

  function showSummary(timeline) {
    const s = timeline.summary;
    const parts = [
      [`Sol ${timeline.sol}, ${hhmmss(timeline.start.lmst_h)}–${hhmmss(timeline.end.lmst_h)} LMST`, ""],
      [`${s.commands} command${s.commands === 1 ? "" : "s"} (${s.commands_failed} not completed)`, s.commands_failed ? "bad" : ""],
      [`${fixed(s.distance_m, 2, " m")} driven`, ""],
      [`max position error ${fixed(s.max_position_error_m, 2, " m")}`, ""],
      [`max attitude error ${fixed(s.max_attitude_error_deg, 2, "°")}`, ""],
      [`min HGA margin ${fixed(s.min_hga_margin_deg, 2, "°")}`,
        s.min_hga_margin_deg !== null && s.min_hga_margin_deg < 0 ? "bad" : ""],
      [`max IMU time ${fixed(s.max_imu_integration_s, 0, " s")}`, ""],
      [`${s.frames} frames`, ""],
    ];
    byId("timeline-summary").replaceChildren(...parts.map(([text, cls]) => {
      const span = document.createElement("span");
      span.textContent = text;
      if (cls) span.className = cls;
      return span;
    }));
  }

  // ---- lanes (absolutely positioned divs, in % of the sol's span) -------------------

  function percent(lmst_h) {
    const [x0, x1] = view.span;
    return (100 * (lmst_h - x0)) / (x1 - x0);
  }

  function placed(className, startH, endH) {
    const el = document.createElement("div");
    el.className = className;
    const left = Math.max(0, Math.min(100, percent(startH)));
    const right = Math.max(left, Math.min(100, percent(endH)));
    el.style.left = `${left}%`;
    el.style.width = `${right - left}%`;
    return el;
  }

  function withLabel(el, text) {
    const label = document.createElement("span");
    label.className = "tl-label";
    label.textContent = text;
    el.appendChild(label);
    return el;
  }

  function commandBar(c) {
    const bar = placed(`tl-command status-${c.status}`, c.start.lmst_h, c.end.lmst_h);
    bar.dataset.testid = "timeline-command";
    bar.dataset.status = c.status;
    const reason = c.reason ? `: ${c.reason}` : "";
    const by = c.submitted_by ? `\nsent by ${c.submitted_by}` : "";
    const rerun = c.reruns ? `\nrun again after a restart (${c.reruns}×)` : "";
    bar.title = `${c.command}\n${c.status}${reason}\n${hhmmss(c.start.lmst_h)}–${hhmmss(c.end.lmst_h)} LMST${by}${rerun}`;
    return withLabel(bar, c.command);
  }

  function band(kind, testid, interval) {
    const seg = placed(`tl-seg tl-${kind}-seg ${kind}-${interval.value}`, interval.start.lmst_h, interval.end.lmst_h);
    seg.dataset.testid = testid;
    seg.dataset.value = interval.value;
    seg.title = `${interval.value}\n${hhmmss(interval.start.lmst_h)}–${hhmmss(interval.end.lmst_h)} LMST`;
    return withLabel(seg, interval.value);
  }

  // Events at the same instant share one mark (its tooltip lists them all), so no mark
  // hides another under the pointer; the mark takes the worst severity of its events.
  const SEVERITY_RANK = { info: 0, warning: 1, error: 2 };

  function eventMarks(events) {
    const groups = new Map();
    for (const e of events) {
      const key = e.t_s.toFixed(3);
      if (!groups.has(key)) groups.set(key, { lmst_h: e.lmst_h, texts: [], severity: "info" });
      const g = groups.get(key);
      g.texts.push(e.text);
      if ((SEVERITY_RANK[e.severity] || 0) > SEVERITY_RANK[g.severity]) g.severity = e.severity;
    }
    return [...groups.values()].map((g) => {
      const mark = document.createElement("div");
      mark.className = `tl-event sev-${g.severity}`;
      mark.dataset.severity = g.severity;
      mark.dataset.testid = "timeline-event";
      mark.style.left = `${Math.max(0, Math.min(100, percent(g.lmst_h)))}%`;
      mark.title = `${hhmmss(g.lmst_h)} LMST\n${g.texts.join("\n")}`;
      return mark;
    });
  }

  // Visual odometry steps get their own lane: a green mark per update, red per failure.
  const VO_EVENT = /^VO step \d+\/\d+/;

  function voMarks(events) {
    return events.filter((e) => VO_EVENT.test(e.text)).map((e) => {
      const failed = e.text.includes("failed");
      const mark = document.createElement("div");
      mark.className = `tl-vo ${failed ? "vo-failure" : "vo-update"}`;
      mark.dataset.testid = "timeline-vo";
      mark.dataset.value = failed ? "failure" : "update";
      mark.style.left = `${Math.max(0, Math.min(100, percent(e.lmst_h)))}%`;
      mark.title = `${hhmmss(e.lmst_h)} LMST\n${e.text}`;
      return mark;
    });
  }

  // The Alarms lane (server.alarms): a bar per alarm from its raise to its clear (or the
  // sol's end), coloured by level, hatched for a truth-view channel. Placed by t_s, since
  // an alarm may have been raised on an earlier sol (LMST hours repeat each sol).
  const LMST_HOUR_S = 88775.244 / 24; // a mean solar sol, s
  const ALARM_ROW_PX = 14;
  function drawAlarmLane(timeline) {
    const lane = byId("lane-alarms");
    if (!lane) return;
    const at = (t_s) => timeline.start.lmst_h + (t_s - timeline.start.t_s) / LMST_HOUR_S;
    const alarms = timeline.alarms || [];
    const ends = []; // alarms that overlap in time go on rows of their own
    const rows = alarms.map((a) => {
      let row = ends.findIndex((e) => e <= a.raised.t_s);
      if (row < 0) row = ends.push(0) - 1;
      ends[row] = a.cleared ? a.cleared.t_s : Infinity;
      return row;
    });
    lane.style.height = `${Math.max(2, ends.length) * ALARM_ROW_PX + 2}px`;
    lane.replaceChildren(...alarms.map((a, i) => {
      const end = a.cleared ? a.cleared.t_s : timeline.end.t_s;
      const bar = placed(`tl-alarm level-${a.level}${a.truth ? " truth" : ""}`, at(a.raised.t_s), at(end));
      bar.style.top = `${1 + ALARM_ROW_PX * rows[i]}px`;
      bar.style.height = `${ALARM_ROW_PX - 2}px`;
      bar.dataset.testid = "timeline-alarm";
      bar.dataset.level = a.level;
      bar.dataset.channel = a.channel;
      const cleared = a.cleared ? `cleared ${hhmmss(a.cleared.lmst_h)} LMST` : "not cleared";
      const ack = a.acknowledged ? `acknowledged by ${a.acknowledged.by}` : "not acknowledged";
      bar.title = `${a.level.toUpperCase()}${a.truth ? " (truth view)" : ""}: ${a.message}\n` +
        `raised sol ${a.raised.sol} ${hhmmss(a.raised.lmst_h)} LMST (${a.raised.utc} UTC)\n${cleared}; ${ack}`;
      return withLabel(bar, a.channel);
    }));
  }

  function drawAxis() {
    const track = byId("lane-axis");
    if (!view.span) { track.replaceChildren(); return; }
    const [x0, x1] = view.span;
    const step = tickMinutes(x1 - x0, track.clientWidth || 600);
    const ticks = [];
    for (let m = Math.ceil((x0 * 60) / step) * step; m <= x1 * 60 + 1e-9; m += step) {
      const tick = document.createElement("div");
      tick.className = "tl-tick";
      tick.style.left = `${percent(m / 60)}%`;
      tick.textContent = hhmm(m / 60);
      ticks.push(tick);
    }
    track.replaceChildren(...ticks);
  }

  // A label shows only when it fits inside its bar; bars change width with the panel.
  function fitLabels() {
    for (const label of byId("timeline-lanes").querySelectorAll(".tl-label")) {
      label.classList.toggle("hidden", label.offsetWidth + 8 > label.parentElement.clientWidth);
    }
  }

  function drawLanes(timeline) {
    byId("lane-commands").replaceChildren(...timeline.commands.map(commandBar));
    byId("lane-nate").replaceChildren(...timeline.nate_modes.map((i) => band("nate", "timeline-nate", i)));
    byId("lane-aqf").replaceChildren(...timeline.aqf.map((i) => band("aqf", "timeline-aqf", i)));
    byId("lane-events").replaceChildren(
      ...eventMarks(timeline.events.filter((e) => !VO_EVENT.test(e.text))));
    byId("lane-vo").replaceChildren(...voMarks(timeline.events));
    drawAlarmLane(timeline);
    drawAxis();
    fitLabels();
  }

  // ---- plots (uPlot) ----------------------------------------------------------------

  function plotWidth(container) {
    return Math.max(200, Math.floor(container.clientWidth));
  }

  function errorRange(_u, _min, max) {
    const top = max === null || !(max > 0) ? 1 : max * 1.1;
    return [0, top];
  }

  // The margin's range always holds 0, so the line where pointing fails is on screen.
  function marginRange(_u, min, max) {
    const lo = Math.min(min === null ? -1 : min, 0);
    const hi = Math.max(max === null ? 1 : max, 0);
    const pad = Math.max(0.1 * (hi - lo), 0.1);
    return [lo - pad, hi + pad];
  }

  function drawZeroLine(u) {
    const y = Math.round(u.valToPos(0, "y", true));
    const ctx = u.ctx;
    ctx.save();
    ctx.strokeStyle = PALETTE.zero;
    ctx.lineWidth = Math.max(1, devicePixelRatio);
    ctx.setLineDash([6 * devicePixelRatio, 4 * devicePixelRatio]);
    ctx.beginPath();
    ctx.moveTo(u.bbox.left, y);
    ctx.lineTo(u.bbox.left + u.bbox.width, y);
    ctx.stroke();
    ctx.restore();
  }

  function moveHairline(u) {
    const line = byId("timeline-hairline");
    const left = u.cursor.left;
    if (left === undefined || left < 0 || !view.span) { line.hidden = true; return; }
    line.hidden = false;
    line.style.left = `${Math.max(0, Math.min(100, percent(u.posToVal(left, "x"))))}%`;
  }

  // Estimators run beside SAPP (roverops serve --estimators): one more line each on the
  // error plots, from the frames' "estimators" entries.
  const SIDE_COLOURS = { kinematic_ekf: "#ff8c42", radio_ekf: "#e65ac8" };  // as the 3D view's
  const SIDE_KEYS = { "plot-position-error": "position_error_m", "plot-attitude-error": "attitude_error_deg" };

  function sideNames(frames) {
    const names = new Set();
    for (const f of frames) for (const name of Object.keys(f.estimators || {})) names.add(name);
    return [...names].sort();
  }

  function plotOptions(container, spec, sides = []) {
    const [x0, x1] = view.span;
    const axis = { stroke: PALETTE.dim, grid: { stroke: PALETTE.line, width: 1 }, ticks: { stroke: PALETTE.line, width: 1 } };
    const hooks = { setCursor: [moveHairline] };
    if (spec.zeroLine) hooks.draw = [drawZeroLine];
    return {
      title: spec.title,
      width: plotWidth(container),
      height: PLOT_HEIGHT_PX,
      padding: [10, RIGHT_PAD_PX, 0, 0],
      cursor: { sync: { key: "sol-timeline" }, drag: { x: false, y: false } },
      scales: { x: { time: false, range: () => [x0, x1] }, y: { range: spec.range } },
      axes: [
        { ...axis, size: X_AXIS_PX, incrs: TICK_INCRS_H, space: TICK_SPACE_PX, values: (_u, splits) => splits.map(hhmm) },
        { ...axis, size: GUTTER_PX },
      ],
      series: [
        { label: "LMST", value: (_u, v) => (v === null ? "—" : hhmmss(v)) },
        {
          label: spec.label, stroke: spec.color, width: 1.5,
          value: (_u, v) => (v === null ? "—" : `${v.toFixed(spec.digits)} ${spec.unit}`),
        },
        ...sides.map((name) => ({
          label: name, stroke: SIDE_COLOURS[name] || "#d98cff", width: 1.5,
          value: (_u, v) => (v === null ? "—" : `${v.toFixed(spec.digits)} ${spec.unit}`),
        })),
      ],
      hooks,
    };
  }

  const PLOTS = [
    {
      id: "plot-position-error", title: "Position error (m)", label: "position error",
      unit: "m", digits: 3, color: "#3d8bfd", range: errorRange,
      value: (f) => f.position_error_m,
    },
    {
      id: "plot-attitude-error", title: "Attitude error (deg)", label: "attitude error",
      unit: "°", digits: 3, color: "#6bd48a", range: errorRange,
      value: (f) => f.attitude_error_deg,
    },
    {
      id: "plot-hga-margin", title: "HGA pointing margin (deg)", label: "HGA margin",
      unit: "°", digits: 2, color: "#f0b429", range: marginRange, zeroLine: true,
      // no margin while Earth is below the horizon: a gap in the line
      value: (f) => (f.earth_up && f.hga_margin_deg !== null ? f.hga_margin_deg : null),
    },
  ];

  function destroyPlots() {
    for (const plot of view.plots) plot.destroy();
    view.plots = [];
  }

  function drawPlots(frames) {
    destroyPlots();
    const xs = frames.map((f) => f.lmst_h);
    const names = sideNames(frames);
    for (const spec of PLOTS) {
      const container = byId(spec.id);
      const ys = frames.map((f) => { const v = spec.value(f); return v === undefined ? null : v; });
      const key = SIDE_KEYS[spec.id];
      const sideValues = (name) => frames.map((f) => {
        const e = (f.estimators || {})[name];
        return e && e[key] !== undefined ? e[key] : null;
      });
      // an estimator of position only (radio_ekf) has no attitude line
      const sides = key ? names.filter((name) => sideValues(name).some((v) => v !== null)) : [];
      const sideYs = sides.map(sideValues);
      const data = [xs, ys, ...sideYs];
      view.plots.push(new uPlot(plotOptions(container, spec, sides), data, container));
    }
  }

  // ---- resizing ---------------------------------------------------------------------

  let resizeQueued = false;
  function resize() {
    if (resizeQueued) return;
    resizeQueued = true;
    requestAnimationFrame(() => {
      resizeQueued = false;
      for (const plot of view.plots) {
        const container = plot.root.parentElement;
        const width = plotWidth(container);
        if (width !== plot.width) plot.setSize({ width, height: PLOT_HEIGHT_PX });
      }
      if (view.span) { drawAxis(); fitLabels(); }
    });
  }

  // ---- focus: another panel asks for a moment ("focus", {sol, t_s}) ------------------

  const SOL_S = 88775.244; // a Mars solar day, s: 24 LMST hours

  async function focus({ sol, t_s }) {
    const picker = byId("timeline-sol");
    if (![...picker.options].some((o) => Number(o.value) === sol)) await fillSols({ followLatest: false });
    picker.value = String(sol);
    await pickSol();
    if (!view.span || Number(picker.value) !== sol) return;
    const line = byId("timeline-hairline");
    line.hidden = false;
    line.style.left = `${Math.max(0, Math.min(100, percent(view.start.lmst_h + (24 * (t_s - view.start.t_s)) / SOL_S)))}%`;
  }

  // ---- start ------------------------------------------------------------------------

  function start() {
    byId("rover").addEventListener("change", () => reload({ followLatest: true }));
    byId("timeline-sol").addEventListener("change", pickSol);
    byId("timeline-refresh").addEventListener("click", () => reload({ followLatest: false }));
    window.addEventListener("resize", resize);
    // the panel also changes width without a window resize (a scrollbar comes or goes)
    new ResizeObserver(resize).observe(byId("timeline-panel"));
    byId("timeline-hairline").hidden = true;
    window.roverops.on("focus", focus);
    reload({ followLatest: true });
  }

  // console.js fills the rover picker once it has asked the server for the rovers.
  function whenRoverKnown(then) {
    if (byId("rover").value) { then(); return; }
    const watcher = new MutationObserver(() => {
      if (!byId("rover").value) return;
      watcher.disconnect();
      then();
    });
    watcher.observe(byId("rover"), { childList: true });
  }

  whenRoverKnown(start);
})();
