// The Truth panel: every figure of the simulator's truth in one place, the scores of the
// rover's estimate against it (position and attitude errors, the true HGA error and margin)
// and what only the simulator knows (the true position and suspension), live, and the sol's
// truth summary from the timeline (the true distance, the worst errors, the least margin).
// No real ground system has any of it. The server decides who may see it (roverops serve
// --truth-view, server/access/truth_view.py) and says so in /api/me's sees_truth: the panel,
// and the timeline's truth plots (.truth-only), show only then. Frames without the truth
// (the downlink alone) leave it as it is. Talks to the other panels through the event bus only.
// Across light time (issue 23) the truth comes live while the rover's data on the ground is
// older: such a frame carries the truth's own time (truth_t_s), and the panel marks its
// values "live" and says both times.
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";
import { durationText } from "./lib/commtime.js";
import { lmstAt, lmstText } from "./lib/marstime.js";

const fixed = (v, digits, unit) => (typeof v === "number" ? `${v.toFixed(digits)}${unit}` : "—");
const xyz = (p) => `(${p.map((v) => v.toFixed(2)).join(", ")})`;

function show(me) {
  const sees = Boolean(me && me.sees_truth);
  $("truth-panel").hidden = !sees;
  document.body.classList.toggle("no-truth", !sees);
}

/** @param {import("./lib/bus.js").Frame} f */
function showLive(f) {
  const live = typeof f.truth_t_s === "number";
  $("truth-panel").classList.toggle("live", live);
  $("truth-live").hidden = !live;
  $("truth-live-note").hidden = !live;
  if (!live) return;
  const lmst_h = lmstAt(f.truth_t_s, f);
  const sol = f.sol + Math.floor(lmst_h / 24);
  const behind = f.truth_t_s - f.t_s;
  $("truth-live").dataset.truthTs = String(f.truth_t_s);
  $("truth-live-note").textContent = `The truth now, sol ${sol} ${lmstText(lmst_h, { seconds: false })} LMST; `
    + `the rover's data on the ground is of sol ${f.sol} ${lmstText(f.lmst_h, { seconds: false })} LMST`
    + (behind >= 60 ? `, ${durationText(behind)} behind.` : ".");
}

function onFrame(f) {
  if (f.p_mission_true === undefined) return; // the downlink alone: nothing of the truth
  showLive(f);
  const live = typeof f.truth_t_s === "number";
  const hga = $("hga-margin");
  if (f.earth_up && f.hga_margin_deg !== null) {
    hga.textContent = `${f.hga_margin_deg.toFixed(2)}° (error ${f.hga_error_deg.toFixed(2)}°)`;
    hga.className = f.hga_margin_deg < 0 ? "bad" : "good";
  } else {
    hga.textContent = "Earth below the horizon";
    hga.className = "warn";
  }
  // the error accumulated over the whole mission, in the mission frame (the Rover
  // panel's position is the estimate in the current Site)
  const e = f.p_mission_est, t = f.p_mission_true;
  const error = typeof f.position_error_m === "number" ? f.position_error_m
    : !live && e && t ? Math.hypot(e[0] - t[0], e[1] - t[1], e[2] - t[2]) : null;
  // live, the estimate in the frame is the data's (older), not the one the error is of
  $("position-error").textContent = error === null ? "—"
    : `${error.toFixed(2)} m` + (live ? " (mission frame, 3D)"
      : e && t ? ` (mission frame, 3D: est ${xyz(e)}, true ${xyz(t)} m)` : "");
  $("attitude-error").textContent = fixed(f.attitude_error_deg, 3, "°");
  $("true-position").textContent = t ? `${xyz(t)} m (Site ${xyz(f.p_s_true)} m)` : "—";
  const bogies = (f.bogie_deg || []).map((v) => v.toFixed(1)).join(", ");
  $("true-joints").textContent =
    `rocker ${fixed(f.rocker_deg, 1, "°")}, bogies (${bogies})°`;
}

// The timeline's truth part (GET .../timeline, moved on live by timeline.js).
function onSolTruth({ sol, truth }) {
  const out = $("truth-sol");
  if (!truth) { out.textContent = "—"; return; }
  $("truth-sol-label").textContent = `Sol ${sol}`;
  const margin = truth.min_hga_margin_deg;
  out.replaceChildren(...[
    [`${fixed(truth.distance_m, 2, " m")} driven (true)`, ""],
    [`max position error ${fixed(truth.max_position_error_m, 2, " m")}`, ""],
    [`max attitude error ${fixed(truth.max_attitude_error_deg, 2, "°")}`, ""],
    [`min HGA margin ${fixed(margin, 2, "°")}`, typeof margin === "number" && margin < 0 ? "bad" : ""],
  ].map(([text, cls]) => el("span", { textContent: text, className: cls })));
}

bus.on("me", show);
bus.on("frame", onFrame);
bus.on("sol-truth", onSolTruth);
show(null); // until /api/me has answered
