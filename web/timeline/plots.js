// The sol timeline's plots (uPlot, vendored in /static/vendor/uplot) on the lanes' LMST
// axis: the estimate's errors and the HGA pointing margin, and the hairline over them.
// Across light time a line is not drawn across data the ground does not have (lib/gaps.js:
// a step longer than view.gapS, or the store's reported drops): a point with no value there.
import { $ } from "../lib/dom.js";
import { withBreaks } from "../lib/gaps.js";
import { lmstAt, lmstText } from "../lib/marstime.js";
import { TICK_INCRS_H, TICK_SPACE_PX, view } from "./view.js";
import { drawAxis, fitLabels } from "./lanes.js";

const uPlot = globalThis.uPlot; // a classic script, loaded before the console's modules
// The plots' y axis is this wide and they have no left padding, so their plotting area
// starts where the lanes' tracks start (the lane label column has the same width).
const GUTTER_PX = 72; // = --tl-gutter in console.css
const RIGHT_PAD_PX = 16;
const PLOT_HEIGHT_PX = 150;
const X_AXIS_PX = 30; // room for the hh:mm labels under a plot (uPlot's default is 50)
const PALETTE = { ink: "#dde6ee", dim: "#8a99a8", line: "#2a3642", zero: "#ff6b6b" };

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

// The hairline follows the pointer over the plots; away from them it stays where the
// last "focus" put it (or hides).
function moveHairline(u) {
  const left = u.cursor.left;
  if (left === undefined || left < 0 || !view.span) { placeFocus(); return; }
  setHairline(u.posToVal(left, "x"), false);
}

function setHairline(lmst_h, focused) {
  const line = $("timeline-hairline");
  line.hidden = lmst_h === null;
  line.classList.toggle("focused", focused);
  if (lmst_h !== null) line.style.setProperty("--s", String(lmst_h));
}

export function placeFocus() {
  const f = view.focus;
  const here = f && view.timeline && f.sol === view.sol;
  const line = $("timeline-hairline");
  line.dataset.focusTs = here ? String(f.t_s) : "";
  setHairline(here ? lmstAt(f.t_s, view.timeline.start) : null, Boolean(here));
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
  const axis = { stroke: PALETTE.dim, grid: { stroke: PALETTE.line, width: 1 }, ticks: { stroke: PALETTE.line, width: 1 } };
  const hooks = { setCursor: [moveHairline] };
  if (spec.zeroLine) hooks.draw = [drawZeroLine];
  return {
    title: spec.title,
    width: plotWidth(container),
    height: PLOT_HEIGHT_PX,
    padding: [10, RIGHT_PAD_PX, 0, 0],
    cursor: { sync: { key: "sol-timeline" }, drag: { x: false, y: false } },
    scales: { x: { time: false, range: () => view.span }, y: { range: spec.range } },
    axes: [
      { ...axis, size: X_AXIS_PX, incrs: TICK_INCRS_H, space: TICK_SPACE_PX, values: (_u, splits) => splits.map((h) => lmstText(h, { seconds: false })) },
      { ...axis, size: GUTTER_PX },
    ],
    series: [
      { label: "LMST", value: (_u, v) => (v === null ? "—" : lmstText(v)) },
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

export function destroyPlots() {
  for (const plot of view.plots) plot.destroy();
  view.plots = [];
  view.plotData = [];
}

const sideValue = (f, name, key) => {
  const e = (f.estimators || {})[name];
  return e && e[key] !== undefined ? e[key] : null;
};

// Each plot's uPlot data: [x, its value, the estimators' values beside SAPP]. A null row
// (a hole: withBreaks) is a point halfway between its neighbours with no values.
function plotSeries(frames, spec, sides) {
  const key = SIDE_KEYS[spec.id];
  const value = (f) => { if (!f) return null; const v = spec.value(f); return v === undefined ? null : v; };
  const xs = frames.map((f, i) => (f ? f.lmst_h : (frames[i - 1].lmst_h + frames[i + 1].lmst_h) / 2));
  return [xs, frames.map(value), ...sides.map((name) => frames.map((f) => (f ? sideValue(f, name, key) : null)))];
}

// The frames as plotted: across light time, with a break at each hole.
const broken = (frames) => (view.mission ? withBreaks(frames, view.gapS, view.dropped) : frames);

export function drawPlots(frames) {
  destroyPlots();
  const names = sideNames(frames);
  for (const spec of PLOTS) {
    const container = $(spec.id);
    const key = SIDE_KEYS[spec.id];
    // an estimator of position only (radio_ekf) has no attitude line
    const sides = key ? names.filter((name) => frames.some((f) => sideValue(f, name, key) !== null)) : [];
    const data = plotSeries(broken(frames), spec, sides);
    view.plotData.push({ spec, sides, data });
    view.plots.push(new uPlot(plotOptions(container, spec, sides), data, container));
  }
}

// A live frame's points, pushed onto the plots' arrays (setData at the next render).
export function appendPlots(f) {
  for (const { spec, sides, data } of view.plotData) {
    plotSeries([f], spec, sides).forEach((column, i) => data[i].push(column[0]));
  }
}

// Storage's frames in place of what was plotted live (the same plots, new data).
export function reconcilePlots(frames) {
  view.plotData.forEach((entry, i) => {
    entry.data = plotSeries(broken(frames), entry.spec, entry.sides);
    view.plots[i].setData(entry.data);
  });
}

// ---- resizing ---------------------------------------------------------------------

let resizeQueued = false;
export function resize() {
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