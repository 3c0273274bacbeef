// The sol timeline's lanes: commands, NATE modes, AQF bands, events, VO steps, the images sent
// down (images.js), alarms, faults, the link's windows (comm.js) as absolutely positioned divs
// over the sol's LMST span, and the LMST axis under them.
import { $, el } from "../lib/dom.js";
import { LMST_HOUR_S, lmstAt, lmstText } from "../lib/marstime.js";
import { tickMinutes, view } from "./view.js";
import { commLane } from "./comm.js";
import { imageLane } from "./images.js";
import { rehearsalLane } from "./rehearsal.js";

// ---- lanes (absolutely positioned divs over the sol's span) -----------------------
// Each element carries its LMST start and end as CSS variables (--s, --e) and the lanes
// box the span (--x0, --w): console.css turns them into left and width, so when the span
// grows live only the two variables change and no element is touched.

function percent(lmst_h) {
  const [x0, x1] = view.span;
  return (100 * (lmst_h - x0)) / (x1 - x0);
}

export function applySpan() {
  const lanes = $("timeline-lanes");
  if (!view.span) return;
  lanes.style.setProperty("--x0", String(view.span[0]));
  lanes.style.setProperty("--w", String(view.span[1] - view.span[0]));
}

function setEnd(node, endH) { node.style.setProperty("--e", String(endH)); }

function placed(className, startH, endH) {
  const node = el("div", { className: `${className} tl-placed` });
  node.style.setProperty("--s", String(startH));
  setEnd(node, endH);
  return node;
}

function marked(className, atH) {
  const node = el("div", { className: `${className} tl-at` });
  node.style.setProperty("--s", String(atH));
  return node;
}

function withLabel(node, text) {
  node.appendChild(el("span", { className: "tl-label", textContent: text }));
  return node;
}

// Events as the REST timeline gives them ({t_s, lmst_h, text, kind, severity}); a live
// frame's event is {text, kind, severity, t_s, sol, lmst_h} (or, from an older server, a
// string: then it takes the frame's time).
export function liveEvent(e, f) {
  if (typeof e === "string") return { t_s: f.t_s, lmst_h: f.lmst_h, sol: f.sol, text: e };
  return { ...e, t_s: e.t_s ?? f.t_s, lmst_h: e.lmst_h ?? f.lmst_h, sol: e.sol ?? f.sol };
}

export const eventKey = (e) => `${e.t_s.toFixed(3)}|${e.text}`;

// Commands: one box per stored command (by id; a run again after a restart replaces it).
function commandBar(c) {
  const bar = placed(`tl-command status-${c.status}`, c.start.lmst_h, c.end.lmst_h);
  bar.dataset.testid = "timeline-command";
  bar.dataset.status = c.status;
  bar.dataset.id = String(c.id);
  bar.dataset.sig = JSON.stringify([c.status, c.reason, c.start.t_s, c.end.t_s, c.reruns, c.submitted_by]);
  const reason = c.reason ? `: ${c.reason}` : "";
  const by = c.submitted_by ? `\nsent by ${c.submitted_by}` : "";
  const rerun = c.reruns ? `\nrun again after a restart (${c.reruns}×)` : "";
  bar.title = `${c.command}\n${c.status}${reason}\n${lmstText(c.start.lmst_h)}–${lmstText(c.end.lmst_h)} LMST${by}${rerun}`;
  return withLabel(bar, c.command);
}

const commandLane = {
  id: "lane-commands",
  draw(timeline) { $(this.id).replaceChildren(...timeline.commands.map(commandBar)); },
  command(c) {
    const track = $(this.id);
    const bar = commandBar(c);
    const old = track.querySelector(`[data-id="${c.id}"]`);
    if (!old) track.appendChild(bar);
    else if (old.dataset.sig !== bar.dataset.sig) old.replaceWith(bar);
  },
};

// NATE mode and AQF: bands, one per interval; live, the last one grows or a new starts.
function band(kind, testid, interval) {
  const seg = placed(`tl-seg tl-${kind}-seg ${kind}-${interval.value}`, interval.start.lmst_h, interval.end.lmst_h);
  seg.dataset.testid = testid;
  seg.dataset.value = interval.value;
  seg.dataset.start = String(interval.start.lmst_h);
  bandTitle(seg, interval.start.lmst_h, interval.end.lmst_h);
  return withLabel(seg, interval.value);
}

function bandTitle(seg, startH, endH) {
  seg.title = `${seg.dataset.value}\n${lmstText(startH)}–${lmstText(endH)} LMST`;
}

function bandLane(id, kind, testid, intervalsKey, frameKey) {
  return {
    id,
    draw(timeline) { $(id).replaceChildren(...timeline[intervalsKey].map((i) => band(kind, testid, i))); },
    frame(f) {
      const track = $(id);
      const last = track.lastElementChild;
      if (last) {
        setEnd(last, f.lmst_h);
        bandTitle(last, Number(last.dataset.start), f.lmst_h);
        if (last.dataset.value === String(f[frameKey])) return;
      }
      track.appendChild(band(kind, testid, { value: f[frameKey], start: f, end: f }));
    },
    // Storage's intervals (the WebSocket may have skipped short ones): the bands that
    // agree stay, the first that differs and those after it are replaced.
    reconcile(timeline) {
      const track = $(id);
      const intervals = timeline[intervalsKey];
      const old = [...track.children];
      let i = 0;
      while (i < intervals.length && i < old.length && old[i].dataset.value === String(intervals[i].value)
             && Math.abs(Number(old[i].dataset.start) - intervals[i].start.lmst_h) < 1e-6) {
        setEnd(old[i], intervals[i].end.lmst_h);
        bandTitle(old[i], intervals[i].start.lmst_h, intervals[i].end.lmst_h);
        i++;
      }
      for (const stale of old.slice(i)) stale.remove();
      track.append(...intervals.slice(i).map((iv) => band(kind, testid, iv)));
    },
  };
}

// Events at the same instant share one mark (its tooltip lists them all), so no mark
// hides another under the pointer; the mark takes the worst severity of its events.
// Visual odometry steps get their own lane.
const VO_EVENT = /^VO step \d+\/\d+/;
const SEVERITY_RANK = { info: 0, warning: 1, error: 2 };

function eventMark(e) {
  const mark = marked("tl-event", e.lmst_h);
  mark.dataset.testid = "timeline-event";
  mark.dataset.t = e.t_s.toFixed(3);
  mark.dataset.keys = "";
  return mark;
}

const eventLane = {
  id: "lane-events",
  wants: (e) => !VO_EVENT.test(e.text),
  draw(timeline) {
    $(this.id).replaceChildren();
    for (const e of timeline.events) if (this.wants(e)) this.event(e);
  },
  event(e) {
    const track = $(this.id);
    const key = e.t_s.toFixed(3);
    let mark = track.querySelector(`[data-t="${key}"]`);
    if (!mark) { mark = eventMark(e); mark.dataset.lmst = String(e.lmst_h); track.appendChild(mark); }
    const texts = mark.dataset.texts ? JSON.parse(mark.dataset.texts) : [];
    texts.push(e.text);
    mark.dataset.texts = JSON.stringify(texts);
    const worst = mark.dataset.severity || "info"; // the mark takes its worst event's
    if ((SEVERITY_RANK[e.severity] || 0) > SEVERITY_RANK[worst] || !mark.dataset.severity) {
      mark.dataset.severity = (SEVERITY_RANK[e.severity] || 0) > SEVERITY_RANK[worst] ? e.severity : worst;
      mark.className = mark.className.replace(/ ?sev-\w+/g, "") + ` sev-${mark.dataset.severity}`;
    }
    mark.title = `${lmstText(Number(mark.dataset.lmst))} LMST\n${texts.join("\n")}`;
  },
};

const voLane = {
  id: "lane-vo",
  wants: (e) => VO_EVENT.test(e.text),
  draw(timeline) {
    $(this.id).replaceChildren();
    for (const e of timeline.events) if (this.wants(e)) this.event(e);
  },
  event(e) {
    const failed = e.text.includes("failed");
    const mark = marked(`tl-vo ${failed ? "vo-failure" : "vo-update"}`, e.lmst_h);
    mark.dataset.testid = "timeline-vo";
    mark.dataset.value = failed ? "failure" : "update";
    mark.title = `${lmstText(e.lmst_h)} LMST\n${e.text}`;
    $(this.id).appendChild(mark);
  },
};

// The Alarms lane (server.alarms): a bar per active span of each alarm, raised (or raised
// again) to cleared (or the sol's end, moving on live), so a span where the channel was
// normal shows no bar; coloured by level, hatched for a truth-view channel. Placed by t_s,
// since an alarm may have been raised on an earlier sol (LMST hours repeat each sol).
// Alarm notices replace the sol's alarm by id and redraw this lane only.
const ALARM_ROW_PX = 14;
const spansOf = (a) => a.spans || [{ from_t_s: a.raised.t_s, to_t_s: a.cleared ? a.cleared.t_s : null }];

export const alarmLane = {
  id: "lane-alarms",
  at(t_s) { return lmstAt(t_s, view.timeline.start); },
  draw(timeline) {
    const lane = $(this.id);
    const alarms = timeline.alarms || [];
    const ends = []; // alarms that overlap in time go on rows of their own
    const rows = alarms.map((a) => {
      let row = ends.findIndex((e) => e <= a.raised.t_s);
      if (row < 0) row = ends.push(0) - 1;
      ends[row] = a.cleared ? a.cleared.t_s : Infinity;
      return row;
    });
    lane.style.height = `${Math.max(2, ends.length) * ALARM_ROW_PX + 2}px`;
    lane.replaceChildren(...alarms.flatMap((a, i) => spansOf(a)
      .filter((s) => s.to_t_s === null || s.to_t_s >= timeline.start.t_s)
      .map((s) => this.bar(a, s, rows[i], timeline))));
  },
  bar(a, span, row, timeline) {
    const open = span.to_t_s === null;
    const end = open ? timeline.end.t_s : span.to_t_s;
    const bar = placed(`tl-alarm level-${a.level}${a.truth ? " truth" : ""}`, this.at(span.from_t_s), this.at(end));
    bar.style.top = `${1 + ALARM_ROW_PX * row}px`;
    bar.style.height = `${ALARM_ROW_PX - 2}px`;
    bar.dataset.testid = "timeline-alarm";
    bar.dataset.alarmId = a.id;
    bar.dataset.level = a.level;
    bar.dataset.channel = a.channel;
    bar.dataset.open = open ? "1" : "";
    bar.dataset.fromTs = span.from_t_s;
    bar.dataset.toTs = open ? "" : span.to_t_s;
    const cleared = open ? "not cleared" : `cleared ${lmstText(this.at(span.to_t_s) % 24)} LMST`;
    const ack = a.acknowledged ? `acknowledged by ${a.acknowledged.by}` : "not acknowledged";
    bar.title = `${a.level.toUpperCase()}${a.truth ? " (truth view)" : ""}: ${a.message}\n` +
      `raised sol ${a.raised.sol} ${lmstText(a.raised.lmst_h)} LMST (${a.raised.utc} UTC)` +
      `${a.violations > 1 ? `, ${a.violations} violations` : ""}\nthis span ${lmstText(this.at(span.from_t_s) % 24)} LMST, ${cleared}; ${ack}`;
    return withLabel(bar, a.channel);
  },
  frame(f) { // an alarm not cleared reaches to the newest frame
    for (const bar of $(this.id).querySelectorAll("[data-open='1']")) setEnd(bar, f.lmst_h);
  },
  alarm(a) {
    const alarms = view.timeline.alarms || (view.timeline.alarms = []);
    const known = alarms.findIndex((k) => k.id === a.id);
    if (known >= 0) alarms[known] = a;
    else if (a.raised.t_s <= view.timeline.end.t_s + LMST_HOUR_S && (!a.cleared || a.cleared.t_s >= view.timeline.start.t_s)) alarms.push(a);
    else return;
    this.draw(view.timeline);
  },
  reconcile(timeline) { view.timeline.alarms = timeline.alarms; this.draw(timeline); },
};

// The Faults lane (server/faults): a mark where each fault the conductor injected took
// effect; the timeline lists them in the truth view, and to everyone once revealed.
const faultLane = {
  id: "lane-faults",
  draw(timeline) {
    $(this.id).replaceChildren(...(timeline.faults || []).filter((fault) => fault.applied).map((fault) => {
      const mark = marked("tl-fault", fault.applied.lmst_h);
      mark.dataset.testid = "timeline-fault";
      mark.dataset.faultId = String(fault.fault_id);
      mark.title = `${lmstText(fault.applied.lmst_h)} LMST: fault #${fault.fault_id}, ${fault.description}` +
        `${fault.error ? ` (not applied: ${fault.error})` : ""}${fault.revealed ? "\nrevealed" : "\nnot revealed yet"}`;
      return mark;
    }));
  },
  reconcile(timeline) { view.timeline.faults = timeline.faults; this.draw(timeline); },
};

// The lanes, top to bottom. Each draws itself from a sol's timeline (draw), and may take
// live frames (frame), events (event: those it wants), commands (command) and storage's
// word after live updates (reconcile). A new lane is one more entry.
export const LANES = {
  commands: commandLane,
  rehearsal: rehearsalLane,
  nate: bandLane("lane-nate", "nate", "timeline-nate", "nate_modes", "nate_mode"),
  aqf: bandLane("lane-aqf", "aqf", "timeline-aqf", "aqf", "aqf"),
  events: eventLane,
  vo: voLane,
  images: imageLane,
  alarms: alarmLane,
  faults: faultLane,
  comm: commLane,
};

// Events already drawn (by time and text): a live event storage also gave is not redrawn.
const seenEvents = new Set();

export function addEvent(e) {
  const key = eventKey(e);
  if (seenEvents.has(key)) return;
  seenEvents.add(key);
  for (const lane of Object.values(LANES)) {
    if (lane.event && (!lane.wants || lane.wants(e))) lane.event(e);
  }
}

export function drawAxis() {
  const track = $("lane-axis");
  if (!view.span) { track.replaceChildren(); return; }
  const [x0, x1] = view.span;
  const step = tickMinutes(x1 - x0, track.clientWidth || 600);
  const ticks = [];
  for (let m = Math.ceil((x0 * 60) / step) * step; m <= x1 * 60 + 1e-9; m += step) {
    const tick = el("div", { className: "tl-tick" });
    tick.style.left = `${percent(m / 60)}%`;
    tick.textContent = lmstText(m / 60, { seconds: false });
    ticks.push(tick);
  }
  track.replaceChildren(...ticks);
}

// A label shows only when it fits inside its bar; bars change width with the panel.
export function fitLabels() {
  for (const label of $("timeline-lanes").querySelectorAll(".tl-label")) {
    label.classList.toggle("hidden", label.offsetWidth + 8 > label.parentElement.clientWidth);
  }
}

export function drawLanes(timeline) {
  seenEvents.clear();
  for (const e of timeline.events) seenEvents.add(eventKey(e));
  for (const lane of Object.values(LANES)) lane.draw(timeline);
  drawAxis();
  fitLabels();
}