// roverops console: readouts from the live telemetry WebSocket, commanding over REST.
// Everything comes from the server (a reload loses nothing); the token is kept in this
// browser's sessionStorage, and in an HttpOnly cookie the server sets at sign-in so that
// the telemetry WebSocket and the 3D view can read on a server that needs a token for it.
"use strict";

const $ = (id) => document.getElementById(id);
const state = { rover: null, ws: null, validateTimer: null, diagnosticsTurn: 0, dictionary: [], me: null };
const ROLES = ["viewer", "operator", "conductor", "admin"]; // each may do all before it
const IMU_WARN_S = 10000; // Ali et al. 2005 sec. 4: MER reacquired attitude at about this IMU time

function token() { return state.me && state.me.role ? sessionStorage.getItem("roverops-token") || "" : ""; }
function authHeaders() { const t = token(); return t ? { Authorization: `Bearer ${t}` } : {}; }

// Every call carries the signed-in token (GETs also have the cookie; a POST needs this).
// A request that could not be sent (no network; a header the browser refuses) answers
// status 0 with the browser's reason as its detail, so the caller says it like any refusal.
async function api(path, options = {}) {
  let response;
  try {
    response = await fetch(path, { ...options, headers: { ...authHeaders(), ...(options.headers || {}) } });
  } catch (e) {
    return { ok: false, status: 0, body: { detail: `not sent: ${e.message}` } };
  }
  let body = null;
  try { body = await response.json(); } catch (_) { body = null; }
  const refused = body && typeof body.detail === "string" && body.detail.startsWith("wrong token");
  if (response.status === 403 && refused && token()) await tokenRefused(body.detail);
  return { ok: response.ok, status: response.status, body };
}

// The API refused this tab's token (revoked or expired since sign-in): every call with it
// would be refused, reads too, so the tab forgets it and says so (a refused action says it
// again in its own words), and reads on as whoever it is without it.
async function tokenRefused(detail) {
  sessionStorage.removeItem("roverops-token");
  // a reload right after still says why this tab is signed out (once)
  sessionStorage.setItem("roverops-signed-out", detail);
  state.me = null;
  applyRole(); // at once: no control acts with the forgotten token meanwhile
  $("sequence-status").textContent = `Signed out: ${detail}`;
  const r = await whoAmI("");
  state.me = r.ok ? r.body : null;
  applyRole();
}

// What the API said, as one line: its sentence (401 "token required ...", 403 "wrong
// token: ..." or "... needs the operator role"), or the messages of a 422's list.
function detailText(r) {
  const detail = r.body && r.body.detail;
  if (typeof detail === "string") return detail;
  if (Array.isArray(detail)) return detail.map((e) => (e && e.msg) || JSON.stringify(e)).join("; ");
  return `HTTP ${r.status}`;
}

// The other panels (alarms, queue, event log, plots: one script each) follow the console
// through these hooks rather than reaching into it. Events: "frame" (each live frame),
// "notice" (each typed WebSocket message: {type: "alarm" | "command" | ...}), "state"
// (each /state poll's body), "rover" (the rover picked), "me" (who signed in or out), "live"
// (the telemetry WebSocket of that rover opened: subscribed, so what a REST read made from
// now on misses comes over it).
const roverops = {
  api, lmst, state, mayAct, applyRole, authHeaders, listeners: {},
  on(name, fn) { (this.listeners[name] ||= []).push(fn); },
  emit(name, value) {
    for (const fn of this.listeners[name] || []) {
      try { fn(value); } catch (e) { console.error(`roverops ${name} listener`, e); }
    }
  },
};
window.roverops = roverops;

function lmst(h) {
  const total = Math.floor(h * 3600);
  const hh = String(Math.floor(total / 3600)).padStart(2, "0");
  const mm = String(Math.floor((total % 3600) / 60)).padStart(2, "0");
  const ss = String(total % 60).padStart(2, "0");
  return `${hh}:${mm}:${ss}`;
}

function showFrame(f) {
  if (!f) return;
  $("sol-clock").textContent = `Sol ${f.sol}  ${lmst(f.lmst_h)} LMST`;
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
  roverops.emit("frame", f);
  // Each event at its own time: a message at max speed carries the events of the frames
  // the hub skipped, each stamped with its frame's lmst_h.
  for (const e of f.events || []) showEvent({ lmst_h: f.lmst_h, t_s: f.t_s, ...e });
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
  const li = document.createElement("li");
  li.textContent = `${lmst(e.lmst_h)} ${e.text}`;
  li.className = `sev-${e.severity}`;
  li.dataset.tS = String(e.t_s);
  const list = $("events");
  let next = null; // the newest already shown that is not newer than e
  for (const o of list.children) if (Number(o.dataset.tS) <= e.t_s) { next = o; break; }
  list.insertBefore(li, next);
}

async function fillGap(rover, since) {
  const r = await api(`/api/rovers/${encodeURIComponent(rover)}/events?limit=1000`);
  if (!r.ok || rover !== state.rover) return;
  for (const e of r.body.events) {
    if (e.t_s >= since && !SERVER_KINDS.has(e.kind)) showEvent(e);
  }
}

// The rover's own estimate in its current Site frame (a Site is planted where the rover
// believes it is). The error accumulated over the whole mission, scored against the
// simulator's truth, is the Truth panel's (truth.js), never one number for both.
const xy = (p) => `(${p[0].toFixed(2)}, ${p[1].toFixed(2)})`;
function showPosition(f) {
  $("position").textContent = `Site ${f.site_index}: est ${xy(f.p_s_est)} m`;
}

// The clock as the server runs it: at max with nothing queued it runs in real time
// (server.runtime IDLE_SPEED_AT_MAX), and the header says so rather than "running at max".
function speedLabel(v) { return v === "max" ? "max" : `${v}×`; }
function showClock(c, effective) {
  const now = effective === undefined ? c.speed : effective;
  const idleAtMax = c.speed === "max" && now !== "max";
  const text = `${c.running ? "running" : "paused"} at ${speedLabel(c.running ? now : c.speed)}`;
  $("speed-now").textContent = idleAtMax && c.running ? `${text} (max, idle)` : text;
  $("speed-now").title = idleAtMax
    ? `speed max, nothing queued: the clock runs at ${speedLabel(now)} until work is queued` : "";
  // The selector shows the server's speed, not the last choice made in it (a refused
  // change goes back); it is left alone while a change is on its way.
  const select = $("speed");
  if (state.clockBusy) return;
  const value = String(c.speed);
  if (![...select.options].some((o) => o.value === value)) {
    select.append(new Option(speedLabel(c.speed), value)); // a speed set over the API
  }
  select.value = value;
}

async function refreshState() {
  if (!state.rover) return;
  const r = await api(`/api/rovers/${state.rover}/state`);
  if (r.status === 0 || r.status >= 502) linkLost("the server does not answer");
  else heard();
  if (!r.ok) return;
  const s = r.body;
  roverops.emit("state", s);
  if (s.frame) showFrame({ ...s.frame, events: [] });
  else $("sol-clock").textContent = `Sol ${s.sol}  ${lmst(s.lmst_h)} LMST`;
  $("executing").textContent = s.executing || "—";
  $("queue").textContent = s.queue.length
    ? s.queue.map((q) => `#${q.sequence_id} ${q.name || ""} (${q.next_step}/${q.steps})`).join(", ")
    : "empty";
  const head = s.queue[0];
  $("progress-bar").style.width = head ? `${(100 * head.next_step) / Math.max(1, head.steps)}%` : "0";
  showClock(s.clock, s.effective_speed);
}

async function refreshSequences() {
  if (!state.rover) return;
  const r = await api(`/api/rovers/${state.rover}/sequences`);
  if (!r.ok) return;
  const body = $("sequences").querySelector("tbody");
  body.replaceChildren(...r.body.slice(0, 12).map((s) => {
    const tr = document.createElement("tr");
    for (const v of [s.id, s.name, s.submitted_by || "", s.status, s.detail || ""]) {
      const td = document.createElement("td");
      td.textContent = v;
      tr.appendChild(td);
    }
    return tr;
  }));
}

function connect() {
  if (state.ws) state.ws.close();
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${scheme}://${location.host}/ws/rovers/${state.rover}/telemetry`);
  ws.onopen = () => {
    if (state.ws !== ws) return;
    if (roverEvents.connections++ > 0) fillGap(state.rover, roverEvents.last);
    roverops.emit("live", state.rover);
  };
  ws.onmessage = (m) => {
    const message = JSON.parse(m.data);
    if (message.type) roverops.emit("notice", message);
    else showFrame(message);
  };
  ws.onclose = () => {
    if (state.ws !== ws) return;
    refreshState(); // at once: the poll tells a dead server from a socket that just closed
    setTimeout(connect, 1000);
  };
  state.ws = ws;
}

// ---- the link to the server: a dead server must not look alive ---------------------------
// The /state poll not answered (the socket closing asks it at once), or nothing heard for
// LINK_SILENT_S (a server that hangs): the link is lost. A banner says since when and why,
// and the readouts are greyed with their age. When a poll is answered again the banner
// goes, and the rover's panels reload from storage as a rover pick does: the server may
// have restarted (it lists its restart in the event log and on the timeline).
const LINK_SILENT_S = 4;
const STALE_WHEN_LOST = ["readouts", "sol-clock", "speed-now"];
const link = { heardMs: Date.now(), lostMs: null, why: "" };

function heard() {
  link.heardMs = Date.now();
  if (link.lostMs === null) return;
  link.lostMs = null;
  showLink();
  $("rover").dispatchEvent(new Event("change")); // everything again, from the server
}

function linkLost(why) {
  if (link.lostMs !== null) return;
  link.lostMs = Date.now();
  link.why = why;
  showLink();
}

function showLink() {
  const lost = link.lostMs !== null;
  for (const id of STALE_WHEN_LOST) $(id).classList.toggle("stale", lost);
  $("link-banner").hidden = !lost;
  $("readouts-age").hidden = !lost;
  if (!lost) return;
  const ageS = Math.max(0, Math.round((Date.now() - link.heardMs) / 1000));
  const since = new Date(link.lostMs).toLocaleTimeString();
  $("readouts-age").textContent = `${ageS} s old`;
  $("link-banner").textContent = `Link to the server lost at ${since} (${link.why}): `
    + `the readouts are as last received, ${ageS} s ago. Reconnecting…`;
}

setInterval(() => {
  if (!state.started) return;
  if (Date.now() - link.heardMs > LINK_SILENT_S * 1000) linkLost(`nothing heard for ${LINK_SILENT_S} s`);
  showLink();
}, 1000);

function showDiagnostics(result, list = $("validation")) {
  const items = [...(result.errors || []).map((d) => ["error", d]), ...(result.warnings || []).map((d) => ["warning", d])];
  list.replaceChildren(...items.map(([kind, d]) => {
    const li = document.createElement("li");
    li.className = kind;
    li.textContent = `line ${d.line}:${d.column} ${kind} ${d.code}: ${d.message}`;
    return li;
  }));
}

// A text the server did not check (413 over the upload limit, 429, no network) is not known
// to be valid: the editor's list says why, rather than an empty list that reads as valid.
function showNotChecked(r) {
  const li = document.createElement("li");
  li.className = r.status === 413 ? "error" : "warning";
  li.textContent = `not checked (${r.status || "not sent"}): ${detailText(r)}`;
  $("validation").replaceChildren(li);
}

// The editor's list describes the editor's text (its live check, or its upload); it shows
// the latest answer: a check that returns after an upload of the text (or a newer check)
// was asked for is not shown over it.
async function validateEditor() {
  const turn = ++state.diagnosticsTurn;
  const text = $("editor").value;
  if (!text.trim()) { $("validation").replaceChildren(); return; }
  const r = await api(`/api/sequences/validate?rover=${state.rover}`, {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ text }),
  });
  if (turn !== state.diagnosticsTurn) return;
  if (r.ok && r.body) showDiagnostics(r.body);
  else showNotChecked(r);
}

function uploadStarts() {
  clearTimeout(state.validateTimer);
  state.diagnosticsTurn++;
}

// An upload's outcome goes to the status line, and its diagnostics to the list of what was
// sent: the editor's list for the editor's text, the file's own list (under its name) for a
// file, so that no list describes a text other than the one beside it.
function uploaded(r, fileName) {
  const validated = Boolean(r.body && r.body.errors);
  const outcome = r.body && r.body.status === "queued" ? `Sequence #${r.body.id} queued`
    : validated ? `Rejected: ${r.body.errors.length} error(s), nothing queued`
    : r.status === 401 || r.status === 403 ? `Not uploaded: ${detailText(r)}`
    : `Upload failed (${r.status}): ${detailText(r)}`;
  $("sequence-status").textContent = outcome;
  if (fileName !== undefined) {
    $("file-result-head").textContent = `${fileName}: ${outcome}`;
    showDiagnostics(validated ? r.body : {}, $("file-diagnostics"));
    $("file-result").hidden = false;
  } else {
    $("file-result").hidden = true; // the latest upload is the editor's text
    if (validated) showDiagnostics(r.body);
    else if (r.status === 413) showNotChecked(r); // the text itself is over the limit
  }
  refreshSequences();
}

async function uploadText() {
  uploadStarts();
  const r = await api(`/api/rovers/${state.rover}/sequences`, {
    method: "POST", headers: { ...authHeaders(), "Content-Type": "application/json" },
    body: JSON.stringify({ text: $("editor").value }),
  });
  uploaded(r);
}

// A file is not the editor's text: its upload leaves the editor's check alone.
async function uploadFile() {
  const file = $("file").files[0];
  if (!file) return;
  const form = new FormData();
  form.append("file", file);
  uploaded(await api(`/api/rovers/${state.rover}/sequences`, { method: "POST", headers: authHeaders(), body: form }), file.name);
}

async function clock(body) {
  state.clockBusy = true;
  let r;
  try {
    r = await api(`/api/rovers/${state.rover}/clock`, {
      method: "POST", headers: { ...authHeaders(), "Content-Type": "application/json" }, body: JSON.stringify(body),
    });
  } finally {
    state.clockBusy = false;
  }
  if (!r.ok) $("sequence-status").textContent = `Clock not changed: ${detailText(r)}`;
  await refreshState(); // the selector back to the server's speed if the change was refused
}

// The immediate-command form, built from the command dictionary the server publishes: each
// argument's kind, unit, range and note come from the spec the server validates with, so a
// value out of range is caught here, named with the range the server would quote, before
// anything is sent. Rules across arguments (a note says them) are left to the server.
function currentCommand() { return state.dictionary.find((c) => c.command === $("command").value); }

function argHint(a) {
  const parts = [a.range || a.type.replaceAll("_", " ")];
  if (!a.required) parts.push(a.default === null ? "optional" : `default ${a.default}`);
  if (a.note) parts.push(a.note);
  return `${a.name}: ${parts.join("; ")}`;
}

function argInput(a) {
  let input;
  if (a.type === "boolean") {
    input = document.createElement("select");
    input.append(new Option(a.required ? `${a.name}?` : `${a.name} (default)`, ""),
      new Option("true", "true"), new Option("false", "false"));
  } else {
    input = document.createElement("input");
    if (a.type === "number") {
      input.type = "number";
      input.min = a.min;
      input.max = a.max;
      input.step = "any"; // the ranges are continuous: any decimal inside is valid
    }
    input.placeholder = a.default === null ? a.name : `${a.name} (${a.default})`;
  }
  input.name = a.name;
  input.required = a.required;
  input.title = argHint(a);
  input.dataset.testid = `arg-${a.name}`;
  input.addEventListener("input", () => markArg(input, argProblem(a, input)));
  return input;
}

function renderArgs() {
  const entry = currentCommand();
  const args = entry ? entry.args : [];
  const doc = entry ? entry.doc.replaceAll("``", "").replace(/\s+/g, " ") : "";
  $("command-doc").textContent = [doc, ...args.map(argHint)].join("\n");
  $("args").replaceChildren(...args.map((a) => {
    const field = document.createElement("label");
    field.className = "arg";
    field.append(argInput(a));
    if (a.unit) {
      const unit = document.createElement("span");
      unit.className = "unit";
      unit.textContent = a.unit;
      field.append(unit);
    }
    return field;
  }));
}

// What is wrong with one field, worded as the server words it ("" when nothing is).
function argProblem(a, input) {
  const text = input.value.trim();
  if (input.validity && input.validity.badInput) return `${a.name}: must be a number in ${a.range}`;
  if (text === "") return a.required ? `${a.name}: required${a.range ? `, in ${a.range}` : ""}` : "";
  if (a.type !== "number") return "";
  const v = Number(text);
  const inside = Number.isFinite(v) && (a.min_exclusive ? v > a.min : v >= a.min) && v <= a.max;
  return inside ? "" : `${a.name}: must be in ${a.range}, got ${text}`;
}

function markArg(input, problem) {
  input.classList.toggle("invalid", problem !== "");
  input.setAttribute("aria-invalid", String(problem !== ""));
}

function argValue(a, text) {
  if (a.type === "number") return Number(text);
  if (a.type === "boolean" || a.type === "number_or_boolean") {
    if (text === "true" || text === "on") return true;
    if (text === "false" || text === "off") return false;
  }
  if (a.type === "number_or_boolean" && !Number.isNaN(Number(text))) return Number(text);
  return text; // a string, or a bad value the server will name
}

async function sendCommand() {
  const entry = currentCommand();
  if (!entry) return;
  const status = $("sequence-status");
  const args = {};
  const problems = [];
  for (const a of entry.args) {
    const input = $("args").querySelector(`[name="${a.name}"]`);
    const problem = argProblem(a, input);
    markArg(input, problem);
    if (problem) problems.push(problem);
    else if (input.value.trim() !== "") args[a.name] = argValue(a, input.value.trim());
  }
  if (problems.length) {
    status.textContent = `Not sent: ${problems.join("; ")}`;
    return;
  }
  const r = await api(`/api/rovers/${state.rover}/commands`, {
    method: "POST", headers: { ...authHeaders(), "Content-Type": "application/json" },
    body: JSON.stringify({ command: entry.command, args }),
  });
  if (r.status === 401 || r.status === 403 || r.status === 0) status.textContent = `Not sent: ${detailText(r)}`;
  else if (r.ok) status.textContent = `Command ${entry.command} queued (#${r.body.id})`;
  else {
    const detail = r.body && r.body.detail;
    // every 422's detail is a list of {loc, msg, type}; other errors carry a sentence
    const messages = Array.isArray(detail) ? detail.map((e) => e.msg) : [detailText(r)];
    status.textContent = `Command refused: ${messages.join("; ")}`;
    // a rule across arguments the form cannot check: mark the field the server names
    for (const input of $("args").querySelectorAll("[name]")) {
      if (messages.some((m) => m.includes(`args.${input.name}:`))) markArg(input, "refused");
    }
  }
  refreshSequences();
}

// ---- signing in: who is at this console, and what their role lets them do ----------------

// A role above viewer acts with the token this tab holds: a tab that reads with the
// browser's sign-in cookie alone (another tab signed in) would be answered 401 "token
// required", so it may not act until it is signed in itself.
function mayAct(role) {
  const mine = state.me && state.me.role ? ROLES.indexOf(state.me.role) : -1;
  if (ROLES.indexOf(role) > 0 && !token()) return false;
  return mine >= ROLES.indexOf(role);
}

// Controls carry data-role="operator" (the lowest role the server accepts for them): those
// the signed-in role may not use are greyed out and say why.
function applyRole() {
  for (const el of document.querySelectorAll("[data-role]")) {
    const needed = el.dataset.role;
    el.disabled = !mayAct(needed);
    el.title = !el.disabled ? ""
      : cookieOnly() ? `needs the ${needed} role: sign in in this tab (the token is kept per tab)`
      : `needs the ${needed} role: sign in with a ${needed}'s token`;
  }
  const me = state.me;
  const signedIn = Boolean(me && me.role) && !cookieOnly();
  $("who").textContent = signedIn ? `${me.name} · ${me.role}`
    : cookieOnly() ? `${me.name} · reading (sign in to act)`
    : me ? "reading only" : "sign in to view";
  $("who").title = signedIn || cookieOnly() ? $("who").textContent
    : me ? "not signed in: this server lets anyone read; sign in to act" : "this server needs a token to read";
  $("who").dataset.role = signedIn ? me.role : "";
  $("sign-out").hidden = !(me && me.role);
  $("sign-in").hidden = signedIn;
  $("token").hidden = signedIn;
  roverops.emit("me", me);
}

function cookieOnly() { return Boolean(state.me && state.me.role) && !token(); }

async function whoAmI(t) {
  return api("/api/me", { headers: t ? { Authorization: `Bearer ${t}` } : {} });
}

// A refused sign-in is said at the form, where the operator is looking (and in the status
// line, the console's record of the last thing done); typing again puts it away.
function signInError(text) {
  $("sign-in-error").textContent = text;
  $("sign-in-error").hidden = !text;
  $("token").setAttribute("aria-invalid", String(Boolean(text)));
}

async function signIn() {
  const t = $("token").value.trim();
  const status = $("sequence-status");
  if (!t) { signInError("Paste your API token, then Sign in."); return; }
  // The token goes in the body (any character a token may hold; a header takes Latin-1
  // only), is checked, and sets the reading cookie; 403 says why it is refused.
  const r = await api("/api/session", {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ token: t }),
  });
  if (!r.ok) {
    status.textContent = `Not signed in: ${detailText(r)}`;
    signInError(status.textContent);
    return;
  }
  signInError("");
  sessionStorage.setItem("roverops-token", t);
  $("token").value = "";
  state.me = r.body;
  status.textContent = `Signed in as ${r.body.name} (${r.body.role})`;
  applyRole();
  await start();
}

async function signOut() {
  sessionStorage.removeItem("roverops-token");
  await api("/api/session", { method: "DELETE" });
  const r = await whoAmI("");
  state.me = r.ok ? r.body : null;
  $("sequence-status").textContent = "Signed out";
  applyRole();
}

async function init() {
  $("sign-in").addEventListener("click", signIn);
  $("token").addEventListener("keydown", (e) => { if (e.key === "Enter") signIn(); });
  $("token").addEventListener("input", () => signInError(""));
  $("sign-out").addEventListener("click", signOut);
  const kept = sessionStorage.getItem("roverops-token") || "";
  const signedOut = sessionStorage.getItem("roverops-signed-out");
  sessionStorage.removeItem("roverops-signed-out");
  if (signedOut) $("sequence-status").textContent = `Signed out: ${signedOut}`;
  let r = await whoAmI(kept);
  if (!r.ok && kept) { // a token revoked or expired since this tab signed in
    sessionStorage.removeItem("roverops-token");
    $("sequence-status").textContent = `Signed out: ${detailText(r)}`;
    r = await whoAmI("");
  }
  state.me = r.ok ? r.body : null;
  applyRole();
  if (state.me) await start();
}

// What the console shows once it may read (at once on a server with public reading).
async function start() {
  if (state.started) { connect(); return; }
  state.started = true;
  state.dictionary = (await api("/api/commands", { headers: authHeaders() })).body || [];
  $("command").replaceChildren(...state.dictionary.map((c) => new Option(c.command, c.command)));
  $("command").addEventListener("change", renderArgs);
  $("send").addEventListener("click", sendCommand);
  renderArgs();
  applyRole();
  const rovers = (await api("/api/rovers", { headers: authHeaders() })).body || [];
  $("rover").replaceChildren(...rovers.map((r) => new Option(`${r.rover} (${r.site})`, r.rover)));
  state.rover = new URLSearchParams(location.search).get("rover") || (rovers[0] && rovers[0].rover);
  $("rover").value = state.rover;
  roverops.emit("rover", state.rover);
  $("rover").addEventListener("change", () => {
    state.rover = $("rover").value;
    roverops.emit("rover", state.rover);
    $("events").replaceChildren();
    Object.assign(roverEvents, { keys: new Set(), last: -Infinity, connections: 0 });
    connect(); refreshState(); refreshSequences();
  });
  $("pause").addEventListener("click", () => clock({ action: "pause" }));
  $("resume").addEventListener("click", () => clock({ action: "resume" }));
  $("speed").addEventListener("change", () => {
    const v = $("speed").value;
    clock({ speed: v === "max" ? "max" : Number(v) });
  });
  $("editor").addEventListener("input", () => {
    clearTimeout(state.validateTimer);
    state.validateTimer = setTimeout(validateEditor, 300);
  });
  $("upload-text").addEventListener("click", uploadText);
  $("upload-file").addEventListener("click", uploadFile);
  $("file").addEventListener("change", () => { $("file-result").hidden = true; }); // another file
  connect();
  refreshState();
  refreshSequences();
  setInterval(refreshState, 1000);
  setInterval(refreshSequences, 3000);
}

init();
