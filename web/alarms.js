// roverops console: limits and alarms (server.alarms). A banner at the top of the page while
// any alarm is unacknowledged (coloured by the worst level; silent on purpose), the alarm
// list with Acknowledge buttons, and the limits editor. Loaded from REST when the rover or
// the signed-in user changes, then kept current by the WebSocket's alarm notices, so a
// second console sees an acknowledgement without a reload. Talks to the other panels through the event bus only.
import { api, detailText } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";
import { arrivalText } from "./lib/commtime.js";
import { lmstText } from "./lib/marstime.js";

const LIST_LIMIT = 100; // the newest alarms listed (done ones greyed)
const view = { rover: null, alarms: new Map(), limits: [], dropped: 0, generation: 0, who: null };

// ---- formatting ---------------------------------------------------------------------

function utcText(iso) { return iso ? `${iso.slice(0, 19).replace("T", " ")} UTC` : "—"; }
function whenText(when) { return `sol ${when.sol} ${lmstText(when.lmst_h)} LMST`; }

function valueText(value, units) {
  if (value === null || value === undefined) return "—";
  if (Array.isArray(value)) return value.length ? value.join(", ") : "none";
  const text = typeof value === "number" ? String(Number(value.toPrecision(4))) : String(value);
  return units ? `${text} ${units}` : text;
}

function truthTag() {
  const tag = el("span", { textContent: "truth view", className: "truth-tag" });
  tag.dataset.testid = "truth-tag";
  tag.title = "scored against the simulator's truth: no real rover reports this";
  return tag;
}

// ---- the banner ---------------------------------------------------------------------

// A shelved alarm is the operators' choice not to be told: not in the banner.
function unacknowledged() {
  return [...view.alarms.values()].filter((a) => !a.acknowledged && !a.shelved);
}

function renderBanner() {
  const banner = $("alarm-banner");
  const open = unacknowledged().sort((a, b) => b.raised.t_s - a.raised.t_s || b.id - a.id);
  banner.hidden = open.length === 0;
  if (!open.length) { banner.replaceChildren(); banner.dataset.level = ""; return; }
  const worst = open.some((a) => a.level === "critical") ? "critical" : "warning";
  const newest = open[0];
  banner.dataset.level = worst;
  const count = el("strong", { textContent: `${worst.toUpperCase()} · ${open.length} unacknowledged alarm${open.length === 1 ? "" : "s"}` });
  count.dataset.testid = "alarm-count";
  const cleared = newest.cleared ? " (cleared since)" : "";
  const message = el("span", { textContent: `${newest.level}: ${newest.message.replace(" (truth view)", "")}${cleared}`, className: "alarm-banner-message" });
  message.dataset.testid = "alarm-banner-message";
  const parts = [count, message];
  if (newest.truth) parts.push(truthTag());
  const truthCount = open.filter((a) => a.truth).length;
  if (truthCount && !newest.truth) parts.push(el("span", { textContent: `(${truthCount} truth view)`, className: "alarm-banner-note" }));
  const link = el("a", { textContent: "show alarms", className: "alarm-banner-link" });
  link.href = "#alarms-panel";
  parts.push(link);
  banner.replaceChildren(...parts);
}

// ---- the list -----------------------------------------------------------------------

function row(a) {
  const tr = el("tr");
  tr.dataset.testid = "alarm-row";
  tr.dataset.alarmId = a.id;
  tr.dataset.level = a.level;
  tr.dataset.channel = a.channel;
  tr.dataset.truth = String(a.truth);
  tr.dataset.acknowledged = String(Boolean(a.acknowledged));
  tr.dataset.cleared = String(Boolean(a.cleared));
  tr.dataset.shelved = String(Boolean(a.shelved));
  tr.className = `alarm level-${a.level}${a.acknowledged && a.cleared ? " done" : ""}`;
  tr.title = a.message;
  const raised = el("td");
  raised.append(el("div", { textContent: utcText(a.raised.utc) }), el("div", { textContent: whenText(a.raised), className: "dim" }));
  // across light time: the data's own time (raised), and when it came down
  if (a.received) {
    const data = el("div", { textContent: arrivalText(a.raised, a.received.t_s - a.raised.t_s), className: "alarm-data-time" });
    data.dataset.testid = "alarm-data-time";
    data.title = `the data that raised it was made at ${utcText(a.raised.utc)} and reached the ground at ${utcText(a.received.utc)}`;
    raised.append(data);
  }
  const channel = el("td", { textContent: a.channel });
  if (a.truth) channel.append(" ", truthTag());
  const level = el("td", { textContent: a.level, className: `alarm-level level-${a.level}` });
  const value = el("td", { textContent: `${valueText(a.value, a.units)} vs ${valueText(a.limit, a.units)}` });
  if (a.violations > 1) value.append(el("div", { textContent: `${a.violations} violations`, className: "dim" }));
  // the value now (the one above raised it, or is its worst)
  const latest = el("td");
  latest.dataset.testid = "alarm-latest";
  if (a.latest) {
    latest.append(el("div", { textContent: a.latest.value === null ? "no value" : valueText(a.latest.value, a.units) }),
      el("div", { textContent: whenText(a.latest), className: "dim" }));
  }
  const shelf = el("div", { className: "alarm-shelf" });
  shelf.dataset.testid = "alarm-shelved";
  if (a.shelved) {
    shelf.textContent = `shelved by ${a.shelved.by} until ${whenText(a.shelved.until)}${a.shelved.reason ? `: ${a.shelved.reason}` : ""}`;
    const off = el("button", { textContent: "Unshelve" });
    off.type = "button"; off.dataset.role = "operator"; off.dataset.testid = "alarm-unshelve";
    off.addEventListener("click", () => shelve(a.id, off, null));
    shelf.append(" ", off);
  } else if (!(a.acknowledged && a.cleared)) {
    const hours = el("select");
    hours.setAttribute("aria-label", `shelve alarm ${a.id} for`);
    hours.dataset.role = "operator";
    for (const h of [1, 4, 12, 24]) hours.append(new Option(`${h} h`, String(h * 3600)));
    const on = el("button", { textContent: "Shelve" });
    on.type = "button"; on.dataset.role = "operator"; on.dataset.testid = "alarm-shelve";
    on.title = "neither raised again nor escalated for that long of the rover's clock";
    on.addEventListener("click", () => shelve(a.id, on, Number(hours.value)));
    shelf.append(hours, " ", on);
  }
  const ack = el("td");
  ack.dataset.testid = "alarm-acknowledged";
  if (a.acknowledged) {
    ack.append(el("div", { textContent: a.acknowledged.by }), el("div", { textContent: utcText(a.acknowledged.at_utc), className: "dim" }));
  } else {
    const button = el("button", { textContent: "Acknowledge" });
    button.type = "button";
    button.dataset.role = "operator";
    button.dataset.testid = "alarm-ack";
    button.addEventListener("click", () => acknowledge(a.id, button));
    ack.append(button);
  }
  const cleared = el("td");
  cleared.dataset.testid = "alarm-cleared";
  if (a.cleared) cleared.append(el("div", { textContent: utcText(a.cleared.utc) }), el("div", { textContent: `${lmstText(a.cleared.lmst_h)} LMST`, className: "dim" }));
  else cleared.textContent = "active";
  cleared.append(shelf);
  tr.append(raised, channel, level, value, latest, ack, cleared);
  return tr;
}

function renderList() {
  const alarms = [...view.alarms.values()].sort((a, b) => {
    const doneA = Boolean(a.acknowledged && a.cleared), doneB = Boolean(b.acknowledged && b.cleared);
    return doneA - doneB || b.raised.t_s - a.raised.t_s || b.id - a.id;
  });
  $("alarm-list").querySelector("tbody").replaceChildren(...alarms.map(row));
  $("alarm-empty").hidden = alarms.length > 0;
  bus.emit("controls", $("alarm-list"));
}

function render() { renderBanner(); renderList(); }

async function acknowledge(id, button) {
  button.disabled = true;
  const r = await api(`/api/alarms/${id}/acknowledge`, { method: "POST" });
  const status = $("alarm-status");
  if (r.ok) { upsert(r.body); status.textContent = `Alarm #${id} acknowledged`; return; }
  status.textContent = `Not acknowledged: ${detailText(r)}`;
  await loadAlarms();
}

async function shelve(id, button, durationS) {
  button.disabled = true;
  const r = durationS === null
    ? await api(`/api/alarms/${id}/unshelve`, { method: "POST" })
    : await api(`/api/alarms/${id}/shelve`, {
      method: "POST", headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ duration_s: durationS }),
    });
  const status = $("alarm-status");
  if (r.ok) { upsert(r.body); status.textContent = `Alarm #${id} ${durationS === null ? "unshelved" : "shelved"}`; return; }
  status.textContent = `Not ${durationS === null ? "unshelved" : "shelved"}: ${detailText(r)}`;
  await loadAlarms();
}

function upsert(alarm) {
  if (alarm.rover !== view.rover) return;
  view.alarms.set(alarm.id, alarm);
  render();
}

async function loadAlarms() {
  const rover = view.rover;
  const generation = ++view.generation;
  const r = await api(`/api/rovers/${encodeURIComponent(rover)}/alarms?limit=${LIST_LIMIT}`);
  if (!r.ok || generation !== view.generation || rover !== view.rover) return;
  view.alarms = new Map(r.body.map((a) => [a.id, a]));
  render();
}

// ---- the limits editor --------------------------------------------------------------

function levelInput(limits, level) {
  let input;
  if (limits.kind === "ordinal") {
    input = el("select");
    input.append(new Option("none", ""), ...limits.values.map((v) => new Option(v, v)));
    input.value = limits[level] ?? "";
  } else {
    input = el("input");
    input.value = limits.kind === "state" ? (limits[level] || []).join(", ") : (limits[level] ?? "");
    input.placeholder = limits.kind === "state" ? "states, comma-separated" : "none";
    if (limits.kind === "numeric") input.inputMode = "decimal";
  }
  input.name = level;
  input.dataset.role = "operator";
  input.setAttribute("aria-label", `${limits.channel} ${level}`);
  return input;
}

function parseLevel(limits, text) {
  const t = text.trim();
  if (limits.kind === "state") return t ? t.split(",").map((s) => s.trim()).filter(Boolean) : [];
  if (t === "") return null;
  if (limits.kind === "ordinal") return t;
  const n = Number(t);
  return Number.isFinite(n) ? n : t; // a bad number goes to the server, which names it
}

function limitsRow(limits) {
  const tr = el("tr");
  tr.dataset.testid = "limits-row";
  tr.dataset.channel = limits.channel;
  const name = el("td", { textContent: limits.channel });
  if (limits.truth) name.append(" ", truthTag());
  name.title = limits.why;
  const rule = limits.kind === "state" ? "in states" : limits.direction === "low" ? "below" : "above";
  const inputs = { warning: levelInput(limits, "warning"), critical: levelInput(limits, "critical") };
  const save = el("button", { textContent: "Save" });
  save.type = "button"; save.dataset.role = "operator"; save.dataset.testid = "limits-save";
  const reset = el("button", { textContent: "Default" });
  reset.type = "button"; reset.dataset.role = "operator"; reset.dataset.testid = "limits-reset";
  reset.title = `default: warning ${valueText(limits.default.warning)}, critical ${valueText(limits.default.critical)}`;
  save.addEventListener("click", () => saveLimits(limits, inputs));
  reset.addEventListener("click", () => resetLimits(limits));
  const edited = limits.edited_by ? `${limits.edited_by}, ${utcText(limits.edited_at)}` : "default";
  const cells = [name, el("td", { textContent: `${rule}${limits.units ? ` (${limits.units})` : ""}` }), el("td"), el("td"), el("td", { textContent: edited, className: "dim" }), el("td")];
  cells[2].append(inputs.warning);
  cells[3].append(inputs.critical);
  cells[5].append(save, " ", reset);
  tr.append(...cells);
  const why = el("tr", { className: "limits-why" });
  const whyCell = el("td", { textContent: limits.why });
  whyCell.colSpan = 6;
  why.append(whyCell);
  return [tr, why];
}

function renderLimits() {
  $("limits-table").querySelector("tbody").replaceChildren(...view.limits.flatMap(limitsRow));
  bus.emit("controls", $("limits-table"));
}

async function loadLimits() {
  const rover = view.rover;
  const r = await api(`/api/rovers/${encodeURIComponent(rover)}/limits`);
  if (!r.ok || rover !== view.rover) return;
  view.limits = r.body;
  renderLimits();
}

async function saveLimits(limits, inputs) {
  const body = {
    warning: parseLevel(limits, inputs.warning.value),
    critical: parseLevel(limits, inputs.critical.value),
  };
  const r = await api(`/api/rovers/${encodeURIComponent(view.rover)}/limits/${limits.channel}`, {
    method: "PUT", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
  });
  $("limits-status").textContent = r.ok ? `Limits of ${limits.channel} saved` : `Not saved: ${detailText(r)}`;
  if (r.ok) await loadLimits();
}

async function resetLimits(limits) {
  const r = await api(`/api/rovers/${encodeURIComponent(view.rover)}/limits/${limits.channel}`, { method: "DELETE" });
  $("limits-status").textContent = r.ok ? `Limits of ${limits.channel} back to the defaults` : `Not reset: ${detailText(r)}`;
  if (r.ok) await loadLimits();
}

// ---- hooks --------------------------------------------------------------------------

function reload() {
  if (!view.rover) return;
  loadAlarms();
  loadLimits();
}

bus.on("rover", (rover) => { view.rover = rover; view.alarms = new Map(); render(); reload(); });
// "me" comes at each role refresh: reload only when who is signed in changed.
bus.on("me", (me) => {
  const who = me ? `${me.name}/${me.role}` : "";
  if (who === view.who) return;
  view.who = who;
  if (view.rover) reload();
});
bus.on("notice", (message) => {
  if (message.dropped_notices > view.dropped) { view.dropped = message.dropped_notices; loadAlarms(); }
  if (message.type === "alarm" && message.alarm) upsert(message.alarm);
});
