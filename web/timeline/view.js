// The sol timeline's shared state: what is shown, and the status line. The panel
// (panel.js), its lanes (lanes.js) and its plots (plots.js) read and move it on.
import { $ } from "../lib/dom.js";

export const TICK_MINUTES = [1, 2, 5, 10, 15, 20, 30, 60, 120, 180, 240, 360, 720];
export const TICK_SPACE_PX = 72; // at least this far between LMST labels
// uPlot rejects increments with more than ~16 decimals (1/60 h has 18): round them.
export const TICK_INCRS_H = TICK_MINUTES.map((m) => Number((m / 60).toFixed(12)));

// The tick step the plots' x axis takes too (uPlot: the smallest increment that leaves
// TICK_SPACE_PX between ticks), so the lanes' ticks line up with the plots' grid.
export function tickMinutes(span_h, width_px) {
  return TICK_MINUTES.find((m) => (width_px * m) / (span_h * 60) >= TICK_SPACE_PX) || TICK_MINUTES.at(-1);
}

// span: the sol's [first, last] LMST hours, the x range of the lanes and the plots.
// sol/timeline: what is shown; lastT: the newest frame shown (t_s); latestSol: the
// rover's newest sol known; plotData: each plot's uPlot data arrays (appended to live)
export const view = {
  rover: null, span: null, plots: [], plotData: [], generation: 0, sol: null, timeline: null,
  lastT: -Infinity, latestSol: null, loading: false, pending: [], focus: null,
  wasBusy: false, liveFrames: 0, lastPosition: null, lastTruePosition: null, droppedNotices: 0,
  // across light time (issue 23): the sol's windows and the link (GET .../comm over the sol),
  // the rover's clock now, the longest step that is not a hole in the data, the store's drops
  comm: null, mission: false, nowT: -Infinity, gapS: Infinity, dropped: [],
};

export function setStatus(text, bad = false) {
  const status = $("timeline-status");
  status.textContent = text;
  status.className = bad ? "timeline-status bad" : "timeline-status";
}
