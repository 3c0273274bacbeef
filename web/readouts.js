// The Rover panel: the readouts of the newest frame (NATE mode, AQF, IMU time, the HGA
// margin the rover predicts, its position estimate and uncertainty, mobility), the sol clock, what runs and what is
// queued, and the rover's own events since the page opened.
import { api } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";
import { lmstText } from "./lib/marstime.js";

const IMU_WARN_S = 10000; // Ali et al. 2005 sec. 4: MER reacquired attitude at about this IMU time
// mission: the rover's link is across light time (/state's comm), so a frame is the newest
// data on the ground, not the rover now; queue: the Queue panel's entries ("queue-shown")
const view = { rover: null, mission: false, queue: [] };

/** @param {import("./lib/bus.js").Frame} f */
function showFrame(f) {
  // across light time the clock is the rover's now (/state), not the data's
  if (!view.mission) $("sol-clock").textContent = `Sol ${f.sol}  ${lmstText(f.lmst_h)} LMST`;
  if (view.mission) $("executing").textContent = f.command ? `${f.command} (in the data)` : "—";
  $("nate-mode").textContent = f.nate_mode;
  const badge = $("aqf");
  badge.textContent = f.aqf;
  badge.className = `badge aqf-${f.aqf}`;
  const imu = $("imu-time");
  imu.textContent = `${Math.round(f.imu_integration_s)} s`;
  imu.className = f.imu_integration_s > IMU_WARN_S ? "warn" : "";
  const predicted = $("hga-margin-predicted");
  const own = f.hga_margin_predicted_deg;
  // Without a heading (TiltOnly, Unknown) the rover predicts 2° minus 180°: not a margin.
  const heading = f.aqf === "Coarse" || f.aqf === "Fine";
  predicted.textContent = !heading ? "no attitude" : own === null || own === undefined ? "—" : `${own.toFixed(2)}°`;
  predicted.className = !heading ? "warn" : own === null || own === undefined ? "" : own < 0 ? "bad" : "good";
  predicted.title = heading ? "" : `AQF ${f.aqf}: the heading is unknown, so the rover cannot predict its HGA margin`;
  showPosition(f);
  // Each event at its own time: a message at max speed carries the events of the frames
  // the hub skipped, each stamped with its frame's lmst_h.
  for (const e of f.events || []) showEvent({ lmst_h: f.lmst_h, t_s: f.t_s, ...e });
}

// The rover's own estimate in its current Site frame (a Site is planted where the rover
// believes it is). The error accumulated over the whole mission, scored against the
// simulator's truth, is the Truth panel's (truth.js), never one number for both.
const xy = (p) => `(${p[0].toFixed(2)}, ${p[1].toFixed(2)})`;
// with the rover's own 2σ (estimation.protection.position_sigma): what its keep-out check uses
function showPosition(f) {
  const sigma = f.position_sigma_m;
  const known = sigma !== null && sigma !== undefined;
  $("position").textContent =
    `Site ${f.site_index}: est ${xy(f.p_s_est)} m` + (known ? ` ± ${(2 * sigma).toFixed(2)} m (2σ)` : "");
  // after a halt the rover refuses drives until the ground clears the fault
  const mobility = $("mobility");
  const fault = f.mobility_fault || "";
  mobility.textContent = fault ? `HALTED: ${fault}` : "enabled";
  mobility.className = fault ? "bad" : "good";
  mobility.title = fault ? "send CLEAR_MOBILITY_FAULT to drive again" : "";
}

function showState(s) {
  view.mission = s.comm === "mission";
  if (!s.frame || view.mission) $("sol-clock").textContent = `Sol ${s.sol}  ${lmstText(s.lmst_h)} LMST`;
  // Across light time /state's executing and queue are the rover's own, which the ground
  // learns a pass later: the panel says what the data says and the queue as the ground
  // knows it (the Queue panel's two sides).
  if (view.mission) { showGroundQueue(); return; }
  $("executing").textContent = s.executing || "—";
  $("queue").textContent = s.queue.length
    ? s.queue.map((q) => `#${q.sequence_id} ${q.name || ""} (${q.next_step}/${q.steps})`).join(", ")
    : "empty";
  const head = s.queue[0];
  $("progress-bar").style.width = head ? `${(100 * head.next_step) / Math.max(1, head.steps)}%` : "0";
}

function showGroundQueue() {
  const ground = view.queue.filter((q) => q.side === "ground").length;
  const onboard = view.queue.filter((q) => q.side === "onboard");
  $("queue").textContent = `${ground} on the ground, ${onboard.length} onboard`;
  const head = onboard.find((q) => q.status === "running");
  $("progress-bar").style.width = head ? `${(100 * head.next_step) / Math.max(1, head.step_count)}%` : "0";
}

// The Rover panel lists the rover's own events (in frames) since the page opened, newest
// first, each once (key: t_s and text). A reconnect brings the ones made while the socket
// was down from the stored log (fillGap).
const SERVER_KINDS = new Set(["sequence", "alarm"]); // the server's events: in no frame
const roverEvents = { keys: new Set(), last: -Infinity, connections: 0 };
function showEvent(e) {
  const key = `${e.t_s}|${e.text}`;
  if (roverEvents.keys.has(key)) return;
  roverEvents.keys.add(key);
  roverEvents.last = Math.max(roverEvents.last, e.t_s);
  const li = el("li", { textContent: `${lmstText(e.lmst_h)} ${e.text}`, className: `sev-${e.severity}` });
  li.dataset.tS = String(e.t_s);
  const list = $("events");
  let next = null; // the newest already shown that is not newer than e
  for (const o of list.children) if (Number(o.dataset.tS) <= e.t_s) { next = o; break; }
  list.insertBefore(li, next);
}

async function fillGap(rover, since) {
  const r = await api(`/api/rovers/${encodeURIComponent(rover)}/events?limit=1000`);
  if (!r.ok || rover !== view.rover) return;
  for (const e of r.body.events) {
    if (e.t_s >= since && !SERVER_KINDS.has(e.kind)) showEvent(e);
  }
}

bus.on("frame", (f) => { if (f) showFrame(f); });
bus.on("state", showState);
bus.on("queue-shown", (queue) => { view.queue = queue; if (view.mission) showGroundQueue(); });
// another rover, or the same one again after the link came back: its list starts afresh
bus.on("rover", (rover) => {
  view.rover = rover;
  $("events").replaceChildren();
  Object.assign(roverEvents, { keys: new Set(), last: -Infinity, connections: 0 });
});
bus.on("live", (rover) => {
  if (rover === view.rover && roverEvents.connections++ > 0) fillGap(rover, roverEvents.last);
});
