// roverops console: the rover picked, the clock, the live telemetry WebSocket and the 1 s
// /state poll, and the link to the server. Everything comes from the server (a reload
// loses nothing). The other panels (one module each) follow it through the event bus
// (lib/bus.js): this module emits "rover", "frame", "notice", "state" and "live".
import { api, detailText } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $ } from "./lib/dom.js";

/** What the console is showing; `ws` is the telemetry WebSocket (tests wait on it). */
export const state = { rover: null, ws: null, started: false, clockBusy: false };

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

async function clock(body) {
  state.clockBusy = true;
  let r;
  try {
    r = await api(`/api/rovers/${state.rover}/clock`, {
      method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
    });
  } finally {
    state.clockBusy = false;
  }
  if (!r.ok) $("sequence-status").textContent = `Clock not changed: ${detailText(r)}`;
  await refreshState(); // the selector back to the server's speed if the change was refused
}

async function refreshState() {
  if (!state.rover) return;
  const r = await api(`/api/rovers/${state.rover}/state`);
  if (r.status === 0 || r.status >= 502) linkLost("the server does not answer");
  else heard();
  if (!r.ok) return;
  const s = r.body;
  bus.emit("state", s);
  if (s.frame) bus.emit("frame", { ...s.frame, events: [] });
  showClock(s.clock, s.effective_speed);
}

function connect() {
  if (state.ws) state.ws.close();
  const scheme = location.protocol === "https:" ? "wss" : "ws";
  const ws = new WebSocket(`${scheme}://${location.host}/ws/rovers/${state.rover}/telemetry`);
  ws.onopen = () => {
    if (state.ws === ws) bus.emit("live", state.rover);
  };
  ws.onmessage = (m) => {
    const message = JSON.parse(m.data);
    if (message.type) bus.emit("notice", message);
    else bus.emit("frame", message);
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

// ---- start: what the console shows once it may read (at once on a server with public
// reading); a sign-in after that reconnects the WebSocket with the new cookie.
async function start() {
  if (state.started) { connect(); return; }
  state.started = true;
  bus.emit("start");
  const rovers = (await api("/api/rovers")).body || [];
  $("rover").replaceChildren(...rovers.map((r) => new Option(`${r.rover} (${r.site})`, r.rover)));
  state.rover = new URLSearchParams(location.search).get("rover") || (rovers[0] && rovers[0].rover);
  $("rover").value = state.rover;
  bus.emit("rover", state.rover);
  $("rover").addEventListener("change", () => {
    state.rover = $("rover").value;
    bus.emit("rover", state.rover);
    connect(); refreshState();
  });
  $("pause").addEventListener("click", () => clock({ action: "pause" }));
  $("resume").addEventListener("click", () => clock({ action: "resume" }));
  $("speed").addEventListener("change", () => {
    const v = $("speed").value;
    clock({ speed: v === "max" ? "max" : Number(v) });
  });
  connect();
  refreshState();
  setInterval(refreshState, 1000);
}

bus.on("may-read", start);
