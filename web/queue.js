// roverops console: the Queue panel. Each queued sequence in the order it will run, each
// expandable to its steps with their status; Up, Down and Cancel for an operator. It follows
// the "queue" notices of the telemetry WebSocket (a snapshot of the queue on every change)
// and, as a fallback, re-reads GET /api/rovers/{rover}/queue when the 1 s /state poll shows
// a queue other than the one drawn. A sequence that has started, or an immediate command,
// keeps its place: the server says why, and its buttons say so too.
// Across light time (the rover's link in mission mode, issue 23) the queue has two sides:
// "On the ground" (waiting for the uplink window, or radiated and on its way) and "Onboard"
// (as the ground knows it, from what has come down); each entry says its latest stage with
// its time (UTC, sol and LMST) and lists its stages when expanded. A cancel of a sequence
// already radiated goes up too: the server answers "cancel-sent", and the panel says so.
// The stages arrive with the downlink, so the panel reads the queue again at each of the
// link's reads ("comm", comm.js) and at each command or event notice.
import { api, detailText, heldToken } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";
import { durationText, momentText } from "./lib/commtime.js";
import { lmstText } from "./lib/marstime.js";
import { mayAct } from "./lib/roles.js";

const panel = $("queue-panel");
const STATUS_WORDS = {
  pending: "pending", running: "running", completed: "done", failed: "failed",
  refused: "refused", halted: "halted", skipped: "skipped",
};
const view = {
  rover: null, me: null, queue: [], recent: [], key: "", open: new Set(), loading: false, again: false,
  mission: false, nowT: null, drawn: "", stateKey: "", cancelSent: new Set(),
};

// what the /state poll lists of the queue, for comparing with what is drawn
const keyOf = (queue) => queue.map((q) => `${q.sequence_id}:${q.next_step}`).join(",");

async function load() {
  if (!view.rover) return;
  if (view.loading) { view.again = true; return; }
  view.loading = true;
  try {
    const rover = view.rover;
    const r = await api(`/api/rovers/${rover}/queue`);
    if (r.ok && rover === view.rover) {
      const drawn = JSON.stringify(r.body);
      if (drawn === view.drawn) return; // nothing new: the panel (and what is open) stays
      view.drawn = drawn;
      view.recent = r.body.recent;
      show(r.body.queue);
    }
  } finally {
    view.loading = false;
    if (view.again) { view.again = false; load(); }
  }
}

function show(queue) {
  view.queue = queue;
  view.key = keyOf(queue);
  if (queue.some((q) => q.side)) view.mission = true;
  for (const id of view.cancelSent) if (!queue.some((q) => q.sequence_id === id)) view.cancelSent.delete(id);
  render();
  bus.emit("queue-shown", queue);
}

function say(text, bad) {
  const status = panel.querySelector(".queue-status");
  status.textContent = text;
  status.classList.toggle("bad", Boolean(bad));
}

async function move(q, to) {
  const r = await api(`/api/rovers/${view.rover}/queue/${q.sequence_id}/move`, {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ to }),
  });
  if (r.ok) {
    say(`Sequence #${q.sequence_id} moved to position ${to + 1}`);
    show(r.body.queue);
  } else {
    say(`Not moved: ${detailText(r)}`, true);
    load();
  }
}

async function cancel(q) {
  const what = `#${q.sequence_id} ${q.name || ""}`.trim();
  const note = q.status === "running" ? " Its step under way runs to its end; the rest are not run." : "";
  if (!window.confirm(`Cancel sequence ${what}?${note}`)) return;
  const r = await api(`/api/sequences/${q.sequence_id}`, { method: "DELETE" });
  if (r.ok && r.body.status === "cancel-sent") {
    view.cancelSent.add(q.sequence_id);
    say(`Cancel of ${what} sent: ${r.body.detail}`);
  } else if (r.ok) say(`Sequence ${what} ${r.body.detail}`);
  else say(`Not cancelled: ${detailText(r)}`, true);
  view.drawn = "";
  load();
}

// A button the queue allows gets data-role (applyRole greys it out for a viewer); one it
// does not allow is disabled with the reason as its title.
function button(label, action, testid, why, run) {
  const b = el("button", { className: `queue-${action}`, textContent: label });
  b.type = "button";
  b.dataset.testid = testid;
  b.setAttribute("aria-label", `${action} ${testid.split("-").pop()}`);
  if (why) {
    b.disabled = true;
    b.title = why;
  } else {
    b.dataset.role = "operator";
    b.disabled = !mayAct(view.me, heldToken(), "operator");
    b.title = b.disabled ? "needs the operator role: sign in with an operator's token" : action;
    b.addEventListener("click", run);
  }
  return b;
}

function when(step) {
  if (!step.start) return "";
  const end = step.end ? `–${lmstText(step.end.lmst_h)}` : "";
  return `${lmstText(step.start.lmst_h)}${end} LMST`;
}

function stepsList(steps) {
  const ol = el("ol", { className: "queue-steps" });
  for (const s of steps) {
    const li = el("li", { className: `queue-step step-${s.status}` });
    li.dataset.testid = "queue-step";
    li.dataset.status = s.status;
    li.append(
      el("span", { className: "step-status", textContent: STATUS_WORDS[s.status] || s.status }),
      el("span", { className: "step-line", textContent: s.line ? `line ${s.line}` : "" }),
      el("span", { className: "step-command", textContent: s.command }),
      el("span", { className: "step-when", textContent: s.tag && s.status === "pending" ? s.tag : when(s) }),
    );
    if (s.reason) li.title = s.reason;
    ol.append(li);
  }
  return ol;
}

function summaryText(q) {
  // a step's frames play out after it computed: the running step can be behind next_step
  const running = q.steps.findIndex((s) => s.status === "running");
  const where = running >= 0 ? `running, step ${running + 1} of ${q.step_count}`
    : q.status === "running" ? `started, step ${Math.min(q.next_step + 1, q.step_count)} of ${q.step_count} next`
      : `${q.step_count} step(s)`;
  return `${q.immediate ? "immediate · " : ""}${where}${q.submitted_by ? ` · by ${q.submitted_by}` : ""}`;
}

// ---- across light time: stages ----------------------------------------------------------

const utcText = (iso) => `${iso.slice(0, 16).replace("T", " ")} UTC`;
const whenText = (m) => `${momentText(m)} (${utcText(m.utc)})`;

function stagesList(stages) {
  const ol = el("ol", { className: "queue-stages" });
  ol.dataset.testid = "queue-stages";
  for (const s of stages) {
    const li = el("li", { className: `queue-stage stage-${s.stage.replace(/\s+/g, "-")}` });
    li.dataset.testid = "queue-stage";
    li.dataset.stage = s.stage;
    li.append(
      el("span", { className: "stage-name", textContent: s.stage }),
      el("span", { className: "stage-when", textContent: s.when ? whenText(s.when) : "" }),
      el("span", { className: "stage-detail", textContent: s.detail || "" }),
    );
    ol.append(li);
  }
  return ol;
}

// What comes next on the ground: when its window radiates it, when it reaches the rover;
// "in N min" moves on with the rover's clock (the /state poll) without a redraw.
function nextSpan(q) {
  const [label, moment] = q.radiate ? ["radiates", q.radiate] : q.arrive ? ["reaches the rover", q.arrive] : [];
  if (!moment) return null;
  const span = el("span", { className: "queue-state queue-next" });
  Object.assign(span.dataset, { testid: "queue-next", label, moment: momentText(moment), tS: String(moment.t_s) });
  setNext(span);
  return span;
}

function setNext(span) {
  const t = Number(span.dataset.tS);
  const soon = view.nowT !== null && t > view.nowT ? `, in ${durationText(t - view.nowT)}` : "";
  span.textContent = `${span.dataset.label} ${span.dataset.moment}${soon}`;
}

function stageSummary(q) {
  const last = (q.stages || []).at(-1);
  const stage = el("span", { className: "queue-stage-now" });
  stage.dataset.testid = "queue-latest-stage";
  stage.dataset.stage = last ? last.stage : "";
  stage.textContent = last ? `${last.stage} ${last.when ? whenText(last.when) : ""}` : q.status;
  const parts = [stage, nextSpan(q)].filter(Boolean);
  if (view.cancelSent.has(q.sequence_id)) {
    const sent = el("span", { className: "queue-cancel-sent", textContent: "cancel sent" });
    sent.dataset.testid = "queue-cancel-sent";
    sent.title = "the cancel goes up in the next uplink window; the rover reports where the sequence stopped";
    parts.push(sent);
  }
  return parts;
}

function item(q, index, queue) {
  const li = el("li", { className: `queue-item queue-${q.status}` });
  li.dataset.testid = "queue-item";
  li.dataset.sequenceId = q.sequence_id;
  if (q.side) { li.dataset.side = q.side; li.dataset.status = q.status; }
  const details = el("details");
  details.open = view.open.has(q.sequence_id);
  details.addEventListener("toggle", () => {
    if (details.open) view.open.add(q.sequence_id);
    else view.open.delete(q.sequence_id);
  });
  const summary = el("summary");
  summary.append(
    el("span", { className: "queue-name", textContent: `#${q.sequence_id} ${q.name || "(unnamed)"}` }),
    el("span", { className: "queue-state", textContent: q.side ? `${q.status} · ${summaryText(q)}` : summaryText(q) }),
  );
  if (q.side) summary.append(...stageSummary(q));
  details.append(summary);
  if (q.stages && q.stages.length) details.append(stagesList(q.stages));
  details.append(stepsList(q.steps));
  const above = queue[index - 1];
  const upWhy = q.pinned || (!above ? "first in the queue" : above.pinned ? `#${above.sequence_id} keeps its place` : "");
  const downWhy = q.pinned || (index === queue.length - 1 ? "last in the queue" : "");
  const buttons = el("span", { className: "queue-buttons" });
  buttons.append(
    button("▲", "up", "queue-up", upWhy, () => move(q, index - 1)),
    button("▼", "down", "queue-down", downWhy, () => move(q, index + 1)),
    button("✕", "cancel", "queue-cancel", "", () => cancel(q)),
  );
  li.append(details, buttons);
  return li;
}

function recentItem(s) {
  const li = el("li", { className: `queue-item queue-left queue-${s.status}` });
  li.dataset.testid = "queue-recent-item";
  li.dataset.sequenceId = s.sequence_id;
  const details = el("details");
  const summary = el("summary");
  summary.append(
    el("span", { className: "queue-name", textContent: `#${s.sequence_id} ${s.name || "(unnamed)"}` }),
    el("span", { className: `queue-state seq-${s.status}`, textContent: s.status }),
  );
  details.append(summary);
  if (s.detail) details.append(el("p", { className: "queue-detail", textContent: s.detail }));
  if (s.stages && s.stages.length) details.append(stagesList(s.stages));
  details.append(stepsList(s.steps));
  li.append(details);
  return li;
}

// In mission mode: the ground's side, then the rover's (as the ground knows it).
function sides() {
  const parts = [];
  for (const [side, title, empty] of [
    ["ground", "On the ground", "Nothing waits on the ground."],
    ["onboard", "Onboard (as the ground knows it)", "Nothing onboard that the ground knows of."],
  ]) {
    const entries = view.queue.filter((q) => q.side === side);
    const list = el("ol", { className: `queue-list queue-side-${side}` });
    list.dataset.testid = `queue-${side}`;
    list.append(...entries.map((q, i, all) => item(q, i, all)));
    const head = el("h3", { className: "queue-subhead", textContent: `${title} (${entries.length})` });
    parts.push(head, entries.length ? list : el("p", { className: "queue-empty", textContent: empty }));
  }
  return parts;
}

function render() {
  const list = el("ol", { className: "queue-list" });
  list.dataset.testid = "queue-list";
  list.append(...view.queue.map((q, i, all) => item(q, i, all)));
  const parts = view.mission ? sides()
    : [view.queue.length ? list : el("p", { className: "queue-empty", textContent: "The queue is empty." })];
  if (view.recent.length) {
    const recent = el("ol", { className: "queue-list queue-recent" });
    recent.dataset.testid = "queue-recent";
    recent.append(...view.recent.map(recentItem));
    parts.push(el("h3", { className: "queue-subhead", textContent: "Left the queue" }), recent);
  }
  const status = panel.querySelector(".queue-status") || el("p", { className: "queue-status" });
  status.dataset.testid = "queue-status";
  panel.replaceChildren(status, ...parts);
}

bus.on("rover", (rover) => {
  view.rover = rover;
  view.queue = [];
  view.recent = [];
  view.drawn = "";
  view.mission = false;
  view.cancelSent.clear();
  view.open.clear();
  render();
  load();
});
bus.on("notice", (n) => {
  if (n.type !== "queue" || n.rover !== view.rover) return;
  const now = new Set(n.queue.map((q) => q.sequence_id));
  const left = view.queue.some((q) => !now.has(q.sequence_id));
  show(n.queue);
  if (left) load(); // and what left it, with its outcome
});
bus.on("state", (s) => {
  if (s.rover !== view.rover) return;
  view.nowT = s.t_s;
  for (const span of panel.querySelectorAll(".queue-next")) setNext(span);
  const mission = s.comm === "mission";
  if (mission !== view.mission) { view.mission = mission; view.drawn = ""; load(); return; }
  // across light time /state's queue is the rover's own: not what the panel draws
  const key = keyOf(s.queue);
  if (mission ? key !== view.stateKey : key !== view.key) load();
  view.stateKey = key;
});
// across light time the stages come down with the data: read the queue again
bus.on("comm", (c) => { if (c.rover === view.rover && c.mode === "mission") load(); });
bus.on("notice", (n) => {
  if (view.mission && (n.type === "command" || n.type === "event")) load();
});
bus.on("me", (me) => { view.me = me; render(); });
render();
