// roverops console: the sol timeline review. A sol's commands, NATE modes, Attitude
// Quality Flags and events as lanes over LMST, with the estimate's errors and the HGA
// pointing margin plotted underneath (uPlot, vendored in /static/vendor/uplot) on the same
// LMST axis, and the sol's telemetry as a CSV download.
// Live: while the shown sol is the rover's current one, frames (the bus's "frame")
// and command notices ("notice", type "command") are appended where they belong (a
// band extended, a command box or event mark added, points pushed to the plots with
// setData) without redrawing the rest; "Follow live" moves to the next sol when the rover
// reaches it. The WebSocket is decimated (server.hub: the newest frame of a batch, with the
// skipped frames' events), so when the rover falls idle the lanes and plots are reconciled
// with storage in place. "focus" ({sol, t_s}, from the event log) shows that sol with the
// hairline at t_s.
// Across light time (the rover's link in mission mode, issue 23) the Comm lane shows the
// sol's windows and passes (comm.js), the span takes in the passes ahead, the plots break
// where data is missing, and the sol is read again when data comes down for it (a frame
// that came down, an event of the sol, or what the link's reads say was received): older
// data fills in after newer, so appending live is not enough.
import { api, getJson } from "../lib/api.js";
import { bus } from "../lib/bus.js";
import { $, el } from "../lib/dom.js";
import { lmstText } from "../lib/marstime.js";
import {
  LANES, addEvent, alarmLane, applySpan, drawAxis, drawLanes, fitLabels, liveEvent,
} from "./lanes.js";
import {
  appendPlots, destroyPlots, drawPlots, placeFocus, reconcilePlots, resize,
} from "./plots.js";
import { setStatus, view } from "./view.js";
import { commPath, receivedSignature, windowsSpan } from "./comm.js";
import { fetchImages } from "./images.js";
import { gapAfterS } from "../lib/gaps.js";

const MAX_POINTS = 2000; // the plots ask the server for at most about this many frames
const MIN_SPAN_H = 1 / 60; // a sol with a single frame still gets a minute of axis
const MAX_PENDING = 5000; // live messages kept while a sol loads
const REFRESH_EVERY_MS = 1500; // across light time, the sol read again at most this often

// ---- data -------------------------------------------------------------------------

const everyS = (timeline) => Math.min(86400, Math.max(0, (timeline.end.t_s - timeline.start.t_s) / MAX_POINTS));

function telemetryPath(rover, timeline) {
  const t0 = timeline.start.t_s, t1 = timeline.end.t_s;
  const every = everyS(timeline);
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
  const picker = $("timeline-sol");
  const sols = await getJson(`/api/rovers/${encodeURIComponent(view.rover)}/sols`);
  const previous = Number(picker.value);
  const wasLatest = picker.options.length > 0 && picker.selectedIndex === picker.options.length - 1;
  picker.replaceChildren(...sols.map((s) => new Option(`Sol ${s}`, String(s))));
  if (!sols.length) return null;
  view.latestSol = Math.max(view.latestSol ?? -1, sols.at(-1));
  const keep = !followLatest && !wasLatest && sols.includes(previous);
  picker.value = String(keep ? previous : sols.at(-1));
  return Number(picker.value);
}

// A load takes the live messages that arrive meanwhile (view.pending) and applies them
// once it has drawn: none is lost, none drawn twice (older than lastT: skipped).
function beginLoad() {
  view.loading = true;
  return ++view.generation; // a later load makes this one's answers stale
}

function endLoad(generation) {
  if (generation !== view.generation) return;
  view.loading = false;
  const pending = view.pending;
  view.pending = [];
  for (const [kind, message] of pending) (kind === "frame" ? onFrame : onCommand)(message);
}

let picked = null; // the console's rover

async function reload({ followLatest }) {
  const rover = picked;
  if (!rover) return;
  const generation = beginLoad();
  if (rover !== view.rover) { view.latestSol = null; view.pending = []; view.nowT = -Infinity; refresh.signature = ""; refresh.receivedT = -Infinity; }
  view.rover = rover;
  setStatus("Loading…");
  try {
    const sol = await fillSols({ followLatest });
    if (generation !== view.generation) return;
    if (sol === null) showEmpty(`No telemetry yet for ${rover}.`);
    else await loadSol(sol, generation);
  } catch (err) {
    if (generation === view.generation) setStatus(`Could not load the timeline: ${err.message}`, true);
  }
  endLoad(generation);
}

async function showSol(sol) {
  const generation = beginLoad();
  const picker = $("timeline-sol");
  if (![...picker.options].some((o) => Number(o.value) === sol)) {
    picker.append(new Option(`Sol ${sol}`, String(sol)));
  }
  picker.value = String(sol);
  try {
    await loadSol(sol, generation);
  } catch (err) {
    if (generation === view.generation) setStatus(`Could not load the timeline: ${err.message}`, true);
  }
  endLoad(generation);
}

function pickSol() { return showSol(Number($("timeline-sol").value)); }

async function fetchSol(sol) {
  const rover = view.rover;
  const timeline = await getJson(`/api/rovers/${encodeURIComponent(rover)}/sols/${sol}/timeline`);
  const [frames, comm, images] = await Promise.all([
    getJson(telemetryPath(rover, timeline)),
    api(commPath(rover, timeline)).then((r) => (r.ok ? r.body : null)), // a server without it: none
    fetchImages(rover, timeline), // the Images lane's (images.js)
  ]);
  timeline.images = images;
  return { timeline, frames, comm };
}

// The sol's link (GET .../comm over the sol): the Comm lane's windows, the plots' holes.
function takeComm(comm, timeline, frames) {
  view.comm = comm;
  view.mission = Boolean(comm && comm.mode === "mission");
  if (comm) view.nowT = Math.max(view.nowT, comm.now.t_s);
  $("timeline-panel").classList.toggle("comm-mission", view.mission);
  view.dropped = view.mission ? comm.gaps.filter((g) => g.priority <= 1) : []; // decimated data or more
  view.gapS = view.mission ? gapAfterS(frames.map((f) => f.t_s), { decimate_s: comm.plan.decimate_s, every_s: everyS(timeline) }) : Infinity;
  const windows = view.mission ? windowsSpan(comm, timeline) : null;
  if (windows) view.span = [Math.min(view.span[0], windows[0]), Math.max(view.span[1], windows[1])];
}

async function loadSol(sol, generation) {
  setStatus("Loading…");
  const { timeline, frames, comm } = await fetchSol(sol);
  if (generation !== view.generation) return;
  const x0 = timeline.start.lmst_h;
  view.span = [x0, Math.max(timeline.end.lmst_h, x0 + MIN_SPAN_H)];
  takeComm(comm, timeline, frames);
  const rover = view.rover;
  view.sol = sol;
  view.timeline = timeline;
  view.lastT = Math.max(timeline.end.t_s, frames.length ? frames.at(-1).t_s : -Infinity);
  view.liveFrames = 0;
  view.lastPosition = frames.length ? frames.at(-1).p_mission_est : null;
  view.lastTruePosition = frames.length ? frames.at(-1).p_mission_true : null;
  if (view.focus && view.focus.sol !== sol) view.focus = null;
  const link = $("timeline-csv");
  link.href = csvPath(rover, sol);
  link.setAttribute("download", `${rover}_sol${sol}.csv`);
  link.removeAttribute("aria-disabled");
  $("timeline-panel").classList.remove("empty");
  showSummary(timeline);
  applySpan();
  drawLanes(timeline);
  drawPlots(frames);
  placeFocus();
  setStatus(`${frames.length} frames plotted`);
}

function showEmpty(message) {
  view.span = null;
  view.sol = null;
  view.timeline = null;
  const link = $("timeline-csv");
  link.removeAttribute("href");
  link.setAttribute("aria-disabled", "true");
  $("timeline-panel").classList.add("empty");
  $("timeline-summary").replaceChildren();
  for (const lane of Object.values(LANES)) $(lane.id).replaceChildren();
  $("lane-axis").replaceChildren();
  destroyPlots();
  setStatus(message);
}

// ---- summary ----------------------------------------------------------------------

function fixed(value, digits, unit) {
  return value === null || value === undefined ? "—" : `${value.toFixed(digits)}${unit}`;
}

function showSummary(timeline) {
  const s = timeline.summary;
  const parts = [
    [`Sol ${timeline.sol}, ${lmstText(timeline.start.lmst_h)}–${lmstText(timeline.end.lmst_h)} LMST`, ""],
    [`${s.commands} command${s.commands === 1 ? "" : "s"} (${s.commands_failed} not completed)`, s.commands_failed ? "bad" : ""],
    [`${fixed(s.distance_m, 2, " m")} driven (estimated)`, ""],
    [`max IMU time ${fixed(s.max_imu_integration_s, 0, " s")}`, ""],
    [`${s.frames} frames`, ""],
  ];
  // the sol's truth part (in the truth view only) is the Truth panel's (truth.js)
  bus.emit("sol-truth", { sol: timeline.sol, truth: timeline.truth || null });
  $("timeline-summary").replaceChildren(...parts.map(([text, cls]) => el("span", { textContent: text, className: cls })));
}


// ---- live -------------------------------------------------------------------------

// One render per animation frame, however many messages came: the span's variables,
// the plots' new data, the axis and the summary.
let renderQueued = false;
function render() {
  if (renderQueued) return;
  renderQueued = true;
  requestAnimationFrame(() => {
    renderQueued = false;
    if (!view.timeline) return;
    applySpan();
    view.plotData.forEach((entry, i) => view.plots[i].setData(entry.data));
    drawAxis();
    fitLabels();
    showSummary(view.timeline);
    setStatus(`live: ${view.liveFrames} frame${view.liveFrames === 1 ? "" : "s"} added since loading`);
  });
}

const following = () => $("timeline-follow").checked;
const showingLatest = () => view.sol !== null && view.sol === view.latestSol;

// The rover reached a sol the picker does not have: offer it, and show it if the
// operator was following the current sol (an older sol on screen is left alone).
function newSol(sol) {
  const wasLatest = showingLatest() || view.timeline === null;
  view.latestSol = sol;
  const picker = $("timeline-sol");
  if (![...picker.options].some((o) => Number(o.value) === sol)) {
    picker.append(new Option(`Sol ${sol}`, String(sol)));
  }
  if (wasLatest && following()) showSol(sol);
}

function onFrame(f) {
  if (!view.rover) return;
  if (view.loading) {
    if (view.pending.length < MAX_PENDING) view.pending.push(["frame", f]);
    return;
  }
  if (view.latestSol === null || f.sol > view.latestSol) {
    newSol(f.sol);
    if (view.loading) { view.pending.push(["frame", f]); return; }
  }
  if (view.mission && f.received_t_s !== undefined) cameDown(f);
  if (!view.timeline || f.sol !== view.sol) return;
  if (f.t_s > view.lastT) appendFrame(f);
  else if (f.events && f.events.length) { addFrameEvents(f); render(); } // a frame the /state poll showed first
}

function addFrameEvents(f) {
  for (const e of f.events || []) {
    const event = liveEvent(e, f);
    if (event.sol === view.sol) addEvent(event);
  }
}

function appendFrame(f) {
  view.lastT = f.t_s;
  view.liveFrames += 1;
  view.span[1] = Math.max(view.span[1], f.lmst_h);
  view.timeline.end = { t_s: f.t_s, lmst_h: f.lmst_h };
  for (const lane of Object.values(LANES)) if (lane.frame) lane.frame(f);
  addFrameEvents(f);
  // across light time a truth-view frame carries the truth live (truth_t_s), not of t_s: the
  // truth plots and summary take the stored truth when the sol is read again
  if (f.truth_t_s === undefined) { appendPlots(f); summarise(f); }
  render();
}

// The summary's figures, moved on by one frame (storage's on the next load).
function summarise(f) {
  const s = view.timeline.summary;
  const more = (a, b) => (a === null || a === undefined ? b : Math.max(a, b));
  if (Number.isFinite(f.imu_integration_s)) s.max_imu_integration_s = more(s.max_imu_integration_s, f.imu_integration_s);
  s.distance_m += step(view.lastPosition, f.p_mission_est);
  view.lastPosition = f.p_mission_est;
  const t = view.timeline.truth;
  if (!t) return;
  if (Number.isFinite(f.position_error_m)) t.max_position_error_m = more(t.max_position_error_m, f.position_error_m);
  if (Number.isFinite(f.attitude_error_deg)) t.max_attitude_error_deg = more(t.max_attitude_error_deg, f.attitude_error_deg);
  if (f.earth_up && Number.isFinite(f.hga_margin_deg)) {
    t.min_hga_margin_deg = t.min_hga_margin_deg === null ? f.hga_margin_deg : Math.min(t.min_hga_margin_deg, f.hga_margin_deg);
  }
  t.distance_m += step(view.lastTruePosition, f.p_mission_true);
  view.lastTruePosition = f.p_mission_true;
}

// The horizontal step between two positions (0 when either is missing), m.
function step(last, now) {
  return last && now ? Math.hypot(now[0] - last[0], now[1] - last[1]) : 0;
}

// A command the rover reported (a "command" notice, as the timeline lists it).
function onCommand(c) {
  if (!view.rover) return;
  if (view.loading) {
    if (view.pending.length < MAX_PENDING) view.pending.push(["command", c]);
    return;
  }
  if (!view.timeline || !showingLatest() || c.end.t_s < view.timeline.start.t_s) return;
  const known = view.timeline.commands.findIndex((k) => k.id === c.id);
  if (known >= 0) view.timeline.commands[known] = c;
  else view.timeline.commands.push(c);
  const s = view.timeline.summary;
  s.commands = view.timeline.commands.length;
  s.commands_failed = view.timeline.commands.filter((k) => k.status !== "completed").length;
  for (const lane of Object.values(LANES)) if (lane.command) lane.command(c);
  view.wasBusy = true; // the command may have run between two /state polls
  render();
}

// An alarm raised, escalated, acknowledged or cleared (an "alarm" notice).
function onAlarm(a) {
  if (!view.rover || a.rover !== view.rover || view.loading || !view.timeline || !showingLatest()) return;
  alarmLane.alarm(a);
  render();
}

// ---- across light time: read the sol again when its data comes down ---------------------

const refresh = { busy: false, again: false, lastMs: 0, timer: null, signature: "", receivedT: -Infinity };

// A frame that came down: new data of the shown sol, or events of it (older data filling in
// comes as its events alone). The truth view's frames repeat the newest data with the truth
// live: those are not new.
function cameDown(f) {
  const fresh = f.received_t_s > refresh.receivedT;
  refresh.receivedT = Math.max(refresh.receivedT, f.received_t_s);
  const ofSol = (fresh && f.sol === view.sol) || (f.events || []).some((e) => e.sol === view.sol);
  if (ofSol) refreshSol();
}

// At most one read at a time and one per REFRESH_EVERY_MS: a pass's data comes in bursts.
function refreshSol() {
  if (!view.timeline || !view.mission) return;
  if (refresh.busy) { refresh.again = true; return; }
  const wait = refresh.lastMs + REFRESH_EVERY_MS - Date.now();
  if (wait > 0) {
    if (!refresh.timer) refresh.timer = setTimeout(() => { refresh.timer = null; refreshSol(); }, wait);
    return;
  }
  refresh.busy = true;
  refresh.lastMs = Date.now();
  reconcile({ anySol: true })
    .catch((err) => setStatus(`Could not read the sol again: ${err.message}`, true))
    .finally(() => {
      refresh.busy = false;
      if (refresh.again) { refresh.again = false; refreshSol(); }
    });
}

// The link's read (comm.js, every 2 s): data came down that no frame announced (older data
// filling in behind newer), or a pass's tally moved on.
function onComm(c) {
  if (!view.rover || c.rover !== view.rover) return;
  view.nowT = Math.max(view.nowT, c.now.t_s);
  const signature = receivedSignature(c);
  if (signature === refresh.signature) return;
  refresh.signature = signature;
  refreshSol();
}

// The rover fell idle after work: storage's word on the sol, patched in place (the
// WebSocket's decimation may have skipped short modes and points). Across light time any
// sol on screen, when its data comes down (anySol).
async function reconcile({ anySol = false } = {}) {
  if (!view.timeline || (!anySol && !showingLatest()) || view.loading) return;
  const generation = view.generation;
  const { timeline, frames, comm } = await fetchSol(view.sol);
  if (generation !== view.generation || view.loading) return;
  takeComm(comm, timeline, frames);
  for (const c of timeline.commands) LANES.commands.command(c);
  for (const lane of Object.values(LANES)) if (lane.reconcile) lane.reconcile(timeline);
  for (const e of timeline.events) addEvent(e);
  view.span[1] = Math.max(view.span[1], timeline.end.lmst_h);
  view.lastT = Math.max(view.lastT, timeline.end.t_s);
  view.timeline = { ...timeline, end: view.lastT > timeline.end.t_s ? view.timeline.end : timeline.end };
  reconcilePlots(frames);
  const panel = $("timeline-panel");
  panel.dataset.reconciled = String(Number(panel.dataset.reconciled || 0) + 1); // for tests
  render();
}

function onState(s) {
  if (!view.rover || s.rover !== view.rover) return;
  view.nowT = Math.max(view.nowT, s.t_s);
  if (view.mission) LANES.comm.tick(view.nowT);
  const busy = Boolean(s.executing) || s.queue.length > 0;
  if (view.wasBusy && !busy) reconcile().catch((err) => setStatus(`Could not reconcile: ${err.message}`, true));
  view.wasBusy = busy;
}

// ---- start ------------------------------------------------------------------------

function start() {
  // the rover picked (at the console's start, and on each change): its newest sol
  bus.on("rover", (rover) => { picked = rover; reload({ followLatest: true }); });
  $("timeline-sol").addEventListener("change", pickSol);
  $("timeline-refresh").addEventListener("click", () => reload({ followLatest: false }));
  $("timeline-follow").addEventListener("change", () => {
    if (following() && !showingLatest()) reload({ followLatest: true });
  });
  window.addEventListener("resize", resize);
  // the panel also changes width without a window resize (a scrollbar comes or goes)
  new ResizeObserver(resize).observe($("timeline-panel"));
  $("timeline-hairline").hidden = true;
  bus.on("frame", onFrame);
  bus.on("notice", (n) => {
    // notices were lost (a client far behind): storage's word once the rover is idle
    if ((n.dropped_notices || 0) > view.droppedNotices) { view.droppedNotices = n.dropped_notices; view.wasBusy = true; }
    if (n.type === "command") onCommand(n.command);
    if (n.type === "alarm") onAlarm(n.alarm);
  });
  bus.on("state", onState);
  bus.on("comm", onComm);
  // a sign-in or out may change whether the timeline has its truth part: read it again
  let seesTruth = false; // until /api/me has answered
  bus.on("me", (me) => {
    const sees = Boolean(me && me.sees_truth);
    if (sees === seesTruth) return;
    seesTruth = sees;
    if (view.sol !== null) showSol(view.sol);
  });
  bus.on("focus", ({ sol, t_s }) => {
    view.focus = { sol, t_s };
    if (view.sol === sol && view.timeline) placeFocus();
    else showSol(sol);
  });
}

start();
