// roverops console: the event log. Every event of the rover, newest first, from
// GET /api/rovers/{rover}/events, filtered by sol, kind, severity and text (the server
// filters; live events from the "frame" hook are matched here against the same filters).
// A row names its sol and LMST; clicking it asks the sol timeline to show that moment
// (the bus's "focus", {sol, t_s}).
// No event is lost between the stored ones and the live ones: the log loads again each time
// the telemetry WebSocket opens (the "live" hook: the server subscribed it before it opened,
// so whatever the load does not list yet comes live; the key drops what both bring), and
// again when the server says this page fell so far behind that it lost events or notices.
import { api, detailText } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";
import { lmstText } from "./lib/marstime.js";

const PAGE = 200; // events per REST page ("Older" loads the next)
const MAX_ROWS = 2000; // live events beyond this drop the oldest rows
const SEVERITIES = ["info", "warning", "error"];
const panel = $("eventlog-panel");
// key: t_s and text (REST and the live feed may both bring an event)
// loaded: events fetched over REST (the next page's offset); restTotal: the events
// matching at the last fetch; liveAdded: matching events the live feed added since
const view = {
  rover: null, generation: 0, keys: new Set(), sols: new Set(), loaded: 0, restTotal: 0, liveAdded: 0,
  dropped: 0, // events and notices this connection lost (server.hub): beyond it, load again
};

const ui = {
  sol: el("select", { id: "eventlog-sol", title: "sol" }, new Option("all sols", "")),
  kind: el("select", { id: "eventlog-kind", title: "kind" }, new Option("all kinds", "")),
  severity: el("select", { id: "eventlog-severity", title: "severity" },
    new Option("all severities", ""), new Option("warning and error", "warning"), new Option("error", "error")),
  text: el("input", { id: "eventlog-text", type: "search", placeholder: "text contains", maxLength: 200 }),
  status: el("span", { id: "eventlog-status", className: "eventlog-status" }),
  rows: el("tbody"),
  older: el("button", { type: "button", textContent: "Older events", hidden: true }),
};
ui.sol.dataset.testid = "eventlog-sol";
ui.kind.dataset.testid = "eventlog-kind";
ui.severity.dataset.testid = "eventlog-severity";
ui.text.dataset.testid = "eventlog-text";
ui.status.dataset.testid = "eventlog-status";
ui.older.dataset.testid = "eventlog-older";

panel.append(
  el("div", { className: "eventlog-head" },
    el("h2", { textContent: "Event log" }), ui.sol, ui.kind, ui.severity, ui.text, ui.status),
  el("div", { className: "eventlog-scroll" },
    el("table", { className: "eventlog-table" },
      el("thead", {}, el("tr", {}, ...["Sol", "LMST", "Kind", "Severity", "Event"].map((h) => el("th", { textContent: h })))),
      ui.rows)),
  ui.older,
);

// ---- filters --------------------------------------------------------------------

function filters() {
  return { sol: ui.sol.value, kind: ui.kind.value, min: ui.severity.value, text: ui.text.value.trim() };
}

function query(f, offset) {
  const q = new URLSearchParams({ limit: String(PAGE), offset: String(offset) });
  if (f.sol !== "") q.set("sol", f.sol);
  if (f.kind) q.set("kind", f.kind);
  if (f.min) q.set("min_severity", f.min);
  if (f.text) q.set("text", f.text);
  return q;
}

function matches(e, f) {
  return (f.sol === "" || Number(f.sol) === e.sol)
    && (!f.kind || e.kind === f.kind)
    && (!f.min || SEVERITIES.indexOf(e.severity) >= SEVERITIES.indexOf(f.min))
    && (!f.text || e.text.toLowerCase().includes(f.text.toLowerCase()));
}

// ---- rows -----------------------------------------------------------------------

function row(e) {
  const tr = el("tr", { className: `sev-${e.severity}`, tabIndex: 0,
    title: `${e.utc || ""}\nshow on the sol timeline` },
    el("td", { textContent: String(e.sol) }),
    el("td", { className: "eventlog-time", textContent: lmstText(e.lmst_h) }),
    el("td", { textContent: e.kind }),
    el("td", { className: "eventlog-severity", textContent: e.severity }),
    el("td", { textContent: e.text }));
  tr.dataset.testid = "eventlog-row";
  tr.dataset.kind = e.kind;
  tr.dataset.severity = e.severity;
  tr.dataset.sol = String(e.sol);
  tr.dataset.tS = String(e.t_s);
  tr.dataset.key = key(e);
  if (view.selected === tr.dataset.key) tr.classList.add("selected"); // kept across reloads
  return tr;
}

function focusRow(tr) {
  for (const other of ui.rows.querySelectorAll(".selected")) other.classList.remove("selected");
  tr.classList.add("selected");
  view.selected = tr.dataset.key;
  bus.emit("focus", { sol: Number(tr.dataset.sol), t_s: Number(tr.dataset.tS) });
}

ui.rows.addEventListener("click", (ev) => {
  const tr = ev.target.closest("tr");
  if (tr) focusRow(tr);
});
ui.rows.addEventListener("keydown", (ev) => {
  const tr = ev.target.closest("tr");
  if (tr && (ev.key === "Enter" || ev.key === " ")) { ev.preventDefault(); focusRow(tr); }
});

const key = (e) => `${e.t_s}|${e.text}`;

function showStatus(message, bad = false) {
  ui.status.textContent = message;
  ui.status.classList.toggle("bad", bad);
}

function countStatus() {
  const shown = ui.rows.children.length;
  const total = Math.max(shown, view.restTotal + view.liveAdded);
  showStatus(`${shown} of ${total} event${total === 1 ? "" : "s"}`);
  ui.older.hidden = view.loaded >= view.restTotal;
}

function addSol(sol) {
  if (view.sols.has(sol)) return;
  view.sols.add(sol);
  const options = [...view.sols].sort((a, b) => b - a).map((s) => new Option(`Sol ${s}`, String(s)));
  const picked = ui.sol.value;
  ui.sol.replaceChildren(new Option("all sols", ""), ...options);
  ui.sol.value = picked;
}

// ---- loading --------------------------------------------------------------------

async function load({ more = false } = {}) {
  const generation = more ? view.generation : ++view.generation;
  const rover = view.rover;
  if (!rover) return;
  if (!more) { view.keys.clear(); view.loaded = 0; ui.rows.replaceChildren(); }
  showStatus("Loading…");
  const r = await api(`/api/rovers/${encodeURIComponent(rover)}/events?${query(filters(), view.loaded)}`);
  if (generation !== view.generation) return; // a newer filter or rover won
  if (!r.ok) {
    showStatus(`Could not load the events: ${detailText(r)}`, true);
    return;
  }
  if (ui.kind.options.length === 1) {
    for (const k of r.body.kinds || []) ui.kind.append(new Option(k, k));
  }
  const fresh = r.body.events.filter((e) => !view.keys.has(key(e)));
  for (const e of fresh) { view.keys.add(key(e)); addSol(e.sol); }
  ui.rows.append(...fresh.map(row));
  view.loaded += r.body.events.length;
  view.restTotal = r.body.total;
  view.liveAdded = 0;
  countStatus();
}

async function loadSols() {
  const r = await api(`/api/rovers/${encodeURIComponent(view.rover)}/sols`);
  if (r.ok) for (const s of r.body) addSol(s);
}

// Newest first by time, whatever order live events arrive in (the hub sends notices, the
// server's own events, before frames). At one moment the server's events (a sequence's
// end, an alarm) come above the rover's, as storage orders them: it writes them after
// the frame that caused them.
const SERVER_KINDS = new Set(["sequence", "alarm"]);
function placeOf(e) {
  const server = SERVER_KINDS.has(e.kind);
  for (const tr of ui.rows.children) {
    const t = Number(tr.dataset.tS);
    if (t < e.t_s || (t === e.t_s && (server || !SERVER_KINDS.has(tr.dataset.kind)))) return tr;
  }
  return null; // older than every row shown
}

function live(frame) {
  const f = filters();
  const fresh = (frame.events || [])
    .map((e) => ({ sol: frame.sol, lmst_h: frame.lmst_h, t_s: frame.t_s, ...e }))
    .filter((e) => !view.keys.has(key(e)));
  for (const e of fresh) {
    view.keys.add(key(e));
    addSol(e.sol);
    if (!matches(e, f)) continue;
    ui.rows.insertBefore(row(e), placeOf(e));
    view.liveAdded += 1;
  }
  while (ui.rows.children.length > MAX_ROWS) ui.rows.lastElementChild.remove();
  if (fresh.length) countStatus();
}

function pickRover(rover) {
  view.rover = rover;
  view.sols.clear();
  ui.sol.replaceChildren(new Option("all sols", ""));
  loadSols();
  load();
}

let textTimer = null;
for (const select of [ui.sol, ui.kind, ui.severity]) select.addEventListener("change", () => load());
ui.text.addEventListener("input", () => {
  clearTimeout(textTimer);
  textTimer = setTimeout(() => load(), 250);
});
ui.older.addEventListener("click", () => load({ more: true }));

bus.on("rover", pickRover);
// reload when who reads changes (a sign-in may open a server that needs a token), not on
// every role refresh the console makes
bus.on("me", (me) => {
  const who = me ? `${me.name}|${me.role}` : "";
  if (who === view.who) return;
  view.who = who;
  if (view.rover) load();
});
// Lost on the way (a client too far behind, server.hub): the stored log has them.
function lostSome(message) {
  const lost = (message.dropped_events || 0) + (message.dropped_notices || 0);
  if (lost <= view.dropped) return false;
  view.dropped = lost;
  load();
  return true;
}
bus.on("frame", (frame) => { if (!lostSome(frame)) live(frame); });
// the server's own events (a sequence started or done, an alarm) are in no frame
bus.on("notice", (n) => {
  if (lostSome(n)) return;
  if (n.type === "event") live({ events: [n.event] });
});
// subscribed (at page load, after a reconnect, for another rover): what came meanwhile
bus.on("live", (rover) => {
  view.dropped = 0;
  if (rover === view.rover) load();
});
