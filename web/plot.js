// roverops console: telemetry at a glance. Any numeric channel of the telemetry frame
// (GET /api/rovers/{rover}/channels) plotted against LMST over a sol or a range of sols
// (GET .../channels/{name}: decimated on the server keeping each bucket's min and max, so a
// spike survives). x is sol + LMST/24 h, labelled "Sol N hh:mm". A channel scored against
// the simulator's truth says so beside the plot. While the range holds the rover's current
// sol, live frames (console.js's "frame" hook) extend the line with setData.
import { getJson } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $ } from "./lib/dom.js";
import { lmstText } from "./lib/marstime.js";

const uPlot = globalThis.uPlot; // vendored (/static/vendor/uplot), a classic script before this one

const MAX_POINTS = 2000;
const HEIGHT_PX = 220;
const DEFAULT_CHANNEL = "hga_margin_deg";
const GROUND_CHANNEL = "hga_margin_predicted_deg";
// tick steps in sols: minutes of LMST, then whole sols
const INCRS = [1, 2, 5, 10, 15, 30, 60, 120, 180, 360, 720].map((m) => Number((m / 1440).toFixed(12)))
  .concat([1, 2, 5, 10]);
const COLOURS = { rover: "#3d8bfd", truth: "#e65ac8" };
const view = { rover: null, channels: new Map(), plot: null, data: null, query: null, lastT: -Infinity,
               latestSol: null, generation: 0, queued: false };

// ---- formatting -------------------------------------------------------------------

const xOf = (sol, lmst_h) => sol + lmst_h / 24;

function xLabel(x) {
  const sol = Math.floor(x + 1e-9);
  return `Sol ${sol} ${lmstText(Math.max(0, (x - sol) * 24), { seconds: false })}`;
}

function setStatus(text, bad = false) {
  const status = $("plot-status");
  status.textContent = text;
  status.className = bad ? "plot-status bad" : "plot-status";
}

// ---- a live frame's value of a channel (the names are the CSV's columns) -----------

const number = (v) => (typeof v === "number" && Number.isFinite(v) ? v : null);

function readChannel(record, name) {
  if (!record) return null;
  if (name in record) return number(record[name]);
  const component = /^(.*)_(\d+)$/.exec(name);
  if (component && Array.isArray(record[component[1]])) return number(record[component[1]][Number(component[2])]);
  for (const [estimator, figures] of Object.entries(record.estimators || {})) {
    if (name.startsWith(`${estimator}_`)) return readChannel(figures, name.slice(estimator.length + 1));
  }
  return null;
}

// ---- the controls -----------------------------------------------------------------

async function loadRover(rover) {
  if (rover !== view.rover) view.latestSol = null;
  view.rover = rover;
  const generation = ++view.generation;
  try {
    const [channels, sols] = await Promise.all([
      getJson(`/api/rovers/${encodeURIComponent(rover)}/channels`),
      getJson(`/api/rovers/${encodeURIComponent(rover)}/sols`),
    ]);
    if (generation !== view.generation) return;
    const select = $("plot-channel");
    const previous = select.value;
    view.channels = new Map(channels.map((c) => [c.name, c]));
    select.replaceChildren(...channels.map((c) => {
      const unit = c.unit ? ` (${c.unit})` : "";
      return new Option(`${c.name}${unit}${c.truth ? " · truth" : ""}`, c.name);
    }));
    // the default is a truth channel: outside the truth view the rover's predicted margin
    select.value = [previous, DEFAULT_CHANNEL, GROUND_CHANNEL].find((n) => view.channels.has(n)) || "";
    if (!sols.length) { showEmpty(`No telemetry yet for ${rover}.`); return; }
    view.latestSol = sols.at(-1);
    for (const id of ["plot-sol-from", "plot-sol-to"]) {
      $(id).min = String(sols[0]);
      $(id).max = String(view.latestSol);
      $(id).value = String(view.latestSol);
    }
    await draw();
  } catch (err) {
    if (generation === view.generation) setStatus(`Could not load the channels: ${err.message}`, true);
  }
}

function showEmpty(message) {
  if (view.plot) view.plot.destroy();
  view.plot = null;
  view.data = null;
  view.query = null;
  $("channel-plot").dataset.points = "0";
  setStatus(message);
}

function chosenRange() {
  const from = Number($("plot-sol-from").value);
  const to = Number($("plot-sol-to").value);
  if (!Number.isInteger(from) || !Number.isInteger(to) || from < 0 || to < from) {
    throw new Error("sols: a whole number from, then a to no smaller");
  }
  return [from, to];
}

// ---- the plot ---------------------------------------------------------------------

async function draw() {
  const generation = ++view.generation;
  const name = $("plot-channel").value;
  const channel = view.channels.get(name);
  if (!channel) return;
  let from, to;
  try { [from, to] = chosenRange(); } catch (err) { setStatus(err.message, true); return; }
  setStatus("Loading…");
  const query = new URLSearchParams({ sol_from: String(from), sol_to: String(to), max_points: String(MAX_POINTS) });
  let series;
  try {
    series = await getJson(`/api/rovers/${encodeURIComponent(view.rover)}/channels/${encodeURIComponent(name)}?${query}`);
  } catch (err) {
    if (generation === view.generation) setStatus(`Could not plot ${name}: ${err.message}`, true);
    return;
  }
  if (generation !== view.generation) return;
  view.query = { name, from, to, channel };
  view.data = [series.t_s.map((_, i) => xOf(series.sol[i], series.lmst_h[i])), series.values];
  view.lastT = series.t_s.length ? series.t_s.at(-1) : -Infinity;
  const truth = $("plot-truth");
  truth.hidden = !channel.truth;
  $("telemetry-panel").classList.toggle("truth", channel.truth);
  const container = $("channel-plot");
  if (view.plot) view.plot.destroy();
  view.plot = new uPlot(options(container, channel), view.data, container);
  container.dataset.points = String(view.data[0].length);
  container.dataset.channel = name;
  const thinned = series.decimated ? ` (of ${series.frames} frames: each bucket's min and max kept)` : "";
  setStatus(`${view.data[0].length} points${thinned}`);
}

function options(container, channel) {
  const axis = { stroke: "#8a99a8", grid: { stroke: "#2a3642", width: 1 }, ticks: { stroke: "#2a3642", width: 1 } };
  const unit = channel.unit ? ` ${channel.unit}` : "";
  return {
    width: Math.max(240, Math.floor(container.clientWidth)),
    height: HEIGHT_PX,
    padding: [10, 16, 0, 0],
    cursor: { drag: { x: true, y: false } },
    scales: { x: { time: false } },
    axes: [
      { ...axis, size: 36, incrs: INCRS, space: 110, values: (_u, splits) => splits.map(xLabel) },
      { ...axis, size: 72, label: channel.unit || undefined, labelSize: 16 },
    ],
    series: [
      { label: "LMST", value: (_u, v) => (v === null ? "—" : xLabel(v)) },
      {
        label: channel.truth ? `${channel.name} (truth)` : channel.name,
        stroke: channel.truth ? COLOURS.truth : COLOURS.rover, width: 1.5,
        points: { show: (u) => u.data[0].length < 200 },
        value: (_u, v) => (v === null ? "—" : `${Number(v.toPrecision(6))}${unit}`),
      },
    ],
  };
}

// A live frame inside the plotted range: one more point, drawn at the next frame.
function onFrame(f) {
  if (view.latestSol !== null && f.sol > view.latestSol) view.latestSol = f.sol;
  if (view.latestSol === null && view.rover) {
    // the rover had no telemetry when the panel loaded: now it has (asked at most every 2 s)
    const now = Date.now();
    if (!(now - (view.emptyRetry || 0) < 2000)) { view.emptyRetry = now; loadRover(view.rover); }
    return;
  }
  const q = view.query;
  if (!q || !view.plot) return;
  if (f.sol < q.from || f.sol > q.to || f.t_s <= view.lastT) return;
  view.lastT = f.t_s;
  view.data[0].push(xOf(f.sol, f.lmst_h));
  view.data[1].push(readChannel(f, q.name));
  if (view.queued) return;
  view.queued = true;
  requestAnimationFrame(() => {
    view.queued = false;
    if (!view.plot) return;
    view.plot.setData(view.data);
    $("channel-plot").dataset.points = String(view.data[0].length);
  });
}

function resize() {
  if (!view.plot) return;
  const width = Math.max(240, Math.floor($("channel-plot").clientWidth));
  if (width !== view.plot.width) view.plot.setSize({ width, height: HEIGHT_PX });
}

// ---- start ------------------------------------------------------------------------

function start() {
  $("plot-channel").addEventListener("change", draw);
  $("plot-sol-from").addEventListener("change", draw);
  $("plot-sol-to").addEventListener("change", draw);
  $("plot-draw").addEventListener("click", draw);
  new ResizeObserver(resize).observe($("telemetry-panel"));
  bus.on("frame", onFrame);
  bus.on("rover", loadRover);
  // the truth channels are listed only in the truth view: a sign-in may change it
  let seesTruth = false; // until /api/me has answered
  bus.on("me", (me) => {
    const sees = Boolean(me && me.sees_truth);
    if (sees !== seesTruth && view.rover) loadRover(view.rover);
    seesTruth = sees;
  });
}

start();
