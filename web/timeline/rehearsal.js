// The sol timeline's Rehearsal lane: the rehearsal the console shows (rehearsal.js, the bus's
// "rehearsal") as each line's predicted band beside the executed steps of the Commands lane:
// the outer band from the 5th percentile of the step's start to the 95th of its end, the
// inner one from its median start to its median end, coloured by the line's verdict. Until
// the rehearsed sequence runs, the bands sit where the rehearsal predicted them (from the
// state reported before it); once it runs, on its start (web/lib/rehearsal.js timelineBands).
// The span is widened to take in bands ahead of the sol's last record.
import { bus } from "../lib/bus.js";
import { $, el } from "../lib/dom.js";
import { SOL_S, lmstAt, lmstText } from "../lib/marstime.js";
import { timelineBands } from "../lib/rehearsal.js";
import { view } from "./view.js";

const shown = { rover: null, summary: null, risk: null };

function band(b, timeline) {
  const at = (t) => lmstAt(t, timeline.start);
  const [s0, s1] = b.outer.map(at);
  const [i0, i1] = b.inner.map(at);
  const node = el("div", {
    className: `tl-rehearsal tl-placed verdict-${b.verdict}`,
    dataset: { testid: "timeline-rehearsal", line: String(b.line), verdict: b.verdict },
    title: `line ${b.line}: ${b.command}\n${b.verdict}\npredicted ${lmstText(s0)}–${lmstText(s1)} LMST (5–95 %), `
      + `median ${lmstText(i0)}–${lmstText(i1)}`,
  });
  node.style.setProperty("--s", String(s0));
  node.style.setProperty("--e", String(s1));
  const inner = el("div", { className: "tl-rehearsal-median" });
  const width = Math.max(s1 - s0, 1e-9);
  inner.style.left = `${(100 * (i0 - s0)) / width}%`;
  inner.style.width = `${(100 * Math.max(0, i1 - i0)) / width}%`;
  node.append(inner, el("span", { className: "tl-label", textContent: `${b.line}` }));
  return node;
}

export const rehearsalLane = {
  id: "lane-rehearsal",
  draw(timeline) {
    const lane = $(this.id);
    const row = [lane, lane.previousElementSibling];
    const mine = shown.risk && shown.rover === view.rover;
    for (const node of row) node.classList.toggle("lane-unused", !mine);
    if (!mine || !timeline) { lane.replaceChildren(); return; }
    const { bands, sequence_id } = timelineBands(shown.summary, shown.risk, timeline.commands);
    const start = timeline.start.t_s;
    const solEnd = start + SOL_S; // the sol ends within a sol of its first record
    const ofSol = bands.filter((b) => b.outer[1] >= start && b.outer[0] <= solEnd);
    lane.dataset.campaign = String(shown.summary.id);
    lane.dataset.executed = sequence_id === null ? "" : String(sequence_id);
    lane.replaceChildren(...ofSol.map((b) => band(b, timeline)));
    const last = Math.max(...ofSol.map((b) => lmstAt(b.outer[1], timeline.start)));
    if (view.span && Number.isFinite(last) && last > view.span[1]) {
      view.span[1] = last;
      const lanes = $("timeline-lanes");
      lanes.style.setProperty("--w", String(view.span[1] - view.span[0]));
      view.plotData.forEach((entry, i) => view.plots[i].setData(entry.data)); // their x range is the span
    }
  },
  reconcile(timeline) { this.draw(timeline); },
  command() { if (view.timeline) this.draw(view.timeline); },
};

bus.on("rehearsal", ({ rover, summary, risk }) => {
  shown.rover = rover;
  shown.summary = summary;
  shown.risk = risk;
  if (view.timeline) rehearsalLane.draw(view.timeline);
});
