// The sol timeline's Comm lane (issue 23): the sol's uplink windows (top row), relay passes
// and direct-to-Earth sessions (bottom row) from GET /api/rovers/{rover}/comm over the sol,
// each with its data volume: what the ground received of a past pass, the capacity of one
// ahead. The store's reported drops are red hatched bars on the bottom row. Shown in mission
// mode only (the panel's class comm-mission). The panel (panel.js) reads the windows with
// the sol (commPath) and keeps them in view.comm.
import { $, el } from "../lib/dom.js";
import { WINDOW_WORDS, hmText, mbitText, momentText } from "../lib/commtime.js";
import { LMST_HOUR_S, SOL_S, lmstAt } from "../lib/marstime.js";
import { view } from "./view.js";

/** The sol's span in TT seconds, midnight to midnight, from its timeline's start. */
export function solSpan(timeline) {
  const midnight = timeline.start.t_s - timeline.start.lmst_h * LMST_HOUR_S;
  return [midnight, midnight + SOL_S];
}

export function commPath(rover, timeline) {
  const [from, to] = solSpan(timeline);
  const query = new URLSearchParams({ from_t_s: from.toFixed(3), to_t_s: to.toFixed(3) });
  return `/api/rovers/${encodeURIComponent(rover)}/comm?${query}`;
}

/** The LMST span [first, last] the sol's windows cover on its axis (0 to 24 h at most), or
 * null without windows: in mission mode the timeline shows the passes ahead too. */
export function windowsSpan(comm, timeline) {
  const windows = (comm && comm.windows) || [];
  if (!windows.length) return null;
  const at = (t_s) => Math.min(24, Math.max(0, lmstAt(t_s, timeline.start)));
  return [Math.min(...windows.map((w) => at(w.start_t_s))), Math.max(...windows.map((w) => at(w.end_t_s)))];
}

/** What the ground has received, in a few numbers: it changes when data comes down. */
export function receivedSignature(comm) {
  if (!comm || comm.mode !== "mission") return "";
  const got = (comm.windows || []).filter((w) => w.kind !== "uplink")
    .map((w) => `${w.start_t_s.toFixed(0)}:${w.received_products ?? 0}`);
  const newest = comm.newest_data && comm.newest_data.received ? comm.newest_data.received.t_s : 0;
  return `${newest}|${got.join(",")}|${(comm.gaps || []).length}`;
}

function placed(className, startH, endH) {
  const node = el("div", { className: `${className} tl-placed` });
  node.style.setProperty("--s", String(startH));
  node.style.setProperty("--e", String(endH));
  return node;
}

function whenClass(w, now_t_s) {
  return w.end_t_s <= now_t_s ? "past" : w.start_t_s <= now_t_s ? "open" : "ahead";
}

function bar(w, timeline) {
  const at = (t_s) => lmstAt(t_s, timeline.start);
  const when = whenClass(w, view.nowT);
  const b = placed(`tl-comm comm-${w.kind} ${when}`, at(w.start_t_s), at(w.end_t_s));
  b.dataset.testid = "timeline-window";
  b.dataset.kind = w.kind;
  b.dataset.when = when;
  b.dataset.startTs = String(w.start_t_s);
  b.dataset.endTs = String(w.end_t_s);
  // the uplink window is not a pass: what came down in the DTE session beside it is the DTE's
  const pass = w.kind !== "uplink";
  const received = pass && w.received_mbit !== null && w.received_mbit !== undefined;
  b.dataset.receivedMbit = received ? String(w.received_mbit) : "";
  const volume = !pass ? `${mbitText(w.capacity_mbit)} up`
    : received ? `${mbitText(w.received_mbit)} received` : when === "ahead" ? `≤ ${mbitText(w.capacity_mbit)}`
      : "nothing received yet";
  b.title = `${WINDOW_WORDS[w.kind]}, ${momentText(w.start)}–${hmText(w.end.lmst_h)} LMST `
    + `(${w.minutes.toFixed(1)} min, peak ${w.peak_elev_deg.toFixed(0)}°)\n`
    + (received ? `received ${mbitText(w.received_mbit)} in ${w.received_products} products; ` : "")
    + `capacity ${mbitText(w.capacity_mbit)} at ${mbitText(w.rate_bps / 1e6)}/s`;
  b.appendChild(el("span", { className: "tl-label", textContent: `${w.kind} ${volume}` }));
  return b;
}

function gapBar(g, timeline) {
  const at = (t_s) => lmstAt(t_s, timeline.start);
  const b = placed("tl-comm comm-gap", at(g.first_t_s), at(g.last_t_s));
  b.dataset.testid = "timeline-gap";
  b.title = `the onboard store dropped ${g.count} products (${mbitText(g.bits / 1e6)}, priority ${g.priority}) `
    + `between ${hmText(at(g.first_t_s) % 24)} and ${hmText(at(g.last_t_s) % 24)} LMST: `
    + "they will never come down";
  return b;
}

export const commLane = {
  id: "lane-comm",
  draw(timeline) {
    const comm = view.comm;
    const [from, to] = solSpan(timeline);
    const lane = $(this.id);
    if (!comm || comm.mode !== "mission") { lane.replaceChildren(); return; }
    const gaps = (comm.gaps || []).filter((g) => g.last_t_s >= from && g.first_t_s <= to);
    lane.replaceChildren(...comm.windows.map((w) => bar(w, timeline)), ...gaps.map((g) => gapBar(g, timeline)));
  },
  reconcile(timeline) { this.draw(timeline); },
  // the rover's clock moved on: a window opens or ends
  tick(now_t_s) {
    for (const b of $(this.id).children) {
      if (!b.dataset.kind) continue;
      const when = whenClass({ start_t_s: Number(b.dataset.startTs), end_t_s: Number(b.dataset.endTs) }, now_t_s);
      if (b.dataset.when === when) continue;
      b.classList.remove(b.dataset.when);
      b.classList.add(when);
      b.dataset.when = when;
    }
  },
};
