// The link across light time (issue 23), in the header and the Rover panel. The header says
// the rover's link: in instant mode the mode and the one-way light time; in mission mode
// also the next pass (relay or direct-to-Earth: its LMST and how soon), the next uplink
// window, and how full the onboard store was when the rover last reported it. The Rover
// panel says how old its data is ("data of sol 412 14:02 LMST, received 9 min ago") and
// greys it when it is older than the link can explain (lib/commtime.js, staleAfterS).
// GET /api/rovers/{rover}/comm is read every POLL_MS while the page is visible, at once when
// the rover or its mode changes; frames that came down (received_t_s) move the data's age on
// between reads. The rover's clock now is the /state poll's. Emits "comm" (the answer).
import { api } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $ } from "./lib/dom.js";
import {
  WINDOW_WORDS, clockText, dataAgeText, durationText, fillText, hmText, mbitText, momentText,
  staleAfterS, untilText,
} from "./lib/commtime.js";

const POLL_MS = 2000;
// view.newest: the newest data on the ground, {t_s, sol, lmst_h, received_t_s|null}
const view = { rover: null, comm: null, mode: null, nowT: null, newest: null, loading: false, again: false };

async function load() {
  if (!view.rover) return;
  if (view.loading) { view.again = true; return; }
  view.loading = true;
  try {
    const rover = view.rover;
    const r = await api(`/api/rovers/${encodeURIComponent(rover)}/comm`);
    if (r.ok && rover === view.rover) {
      const c = r.body;
      view.comm = c;
      view.mode = c.mode;
      view.nowT = Math.max(view.nowT ?? -Infinity, c.now.t_s);
      const nd = c.newest_data;
      if (nd && (!view.newest || nd.data.t_s >= view.newest.t_s)) {
        view.newest = { ...nd.data, received_t_s: nd.received ? nd.received.t_s : null };
      }
      render();
      bus.emit("comm", c);
    }
  } finally {
    view.loading = false;
    if (view.again) { view.again = false; load(); }
  }
}

const hm = (moment) => `${hmText(moment.lmst_h)} LMST`;

function windowTitle(w) {
  const got = w.received_mbit === null ? "" : `; received ${mbitText(w.received_mbit)} (${w.received_products} products)`;
  return `${WINDOW_WORDS[w.kind]} ${momentText(w.start)}–${hm(w.end)} (${w.start.utc.slice(0, 16).replace("T", " ")} UTC), `
    + `${w.minutes.toFixed(1)} min at ${mbitText(w.rate_bps / 1e6)}/s, up to ${mbitText(w.capacity_mbit)}, `
    + `peak elevation ${w.peak_elev_deg.toFixed(0)}°${got}`;
}

function showWindow(id, label, w) {
  const node = $(id);
  node.hidden = false;
  if (!w) { node.textContent = `${label}: none in 3 sols`; node.title = ""; return; }
  const kind = label === "next pass" ? ` ${WINDOW_WORDS[w.kind]}` : "";
  node.textContent = `${label}:${kind} ${hm(w.start)}, ${untilText(view.nowT, w)}`;
  node.title = windowTitle(w);
  node.dataset.kind = w.kind;
  node.dataset.open = String(view.nowT >= w.start_t_s && view.nowT < w.end_t_s);
}

function showStore(store) {
  const node = $("store-fill");
  node.hidden = false;
  if (!store) {
    node.textContent = "store: no report yet";
    node.title = "the rover reports its onboard store at the start of each pass";
    node.dataset.fillPct = "";
    return;
  }
  node.textContent = `store ${fillText(store.fill_pct)} full, at ${momentText(store.reported)}`;
  node.title = `the onboard store as the rover reported it at ${momentText(store.reported)} `
    + `(on the ground at ${momentText(store.received)}): ${mbitText(store.used_bits / 1e6)} of `
    + `${mbitText(store.capacity_bits / 1e6)}, ${store.held} products held, ${store.dropped} dropped`;
  node.dataset.fillPct = String(store.fill_pct);
}

function render() {
  const c = view.comm;
  $("comm").hidden = !c;
  if (!c) return;
  const mission = c.mode === "mission";
  document.querySelector("header").classList.toggle("comm-mission", mission);
  $("comm").dataset.mode = c.mode;
  $("link-mode").textContent = `link: ${c.mode}`;
  $("link-mode").title = mission
    ? "across light time: uplinks wait for their window, the rover's data for a pass"
    : "commands and telemetry cross at once (roverops serve --comm mission: across light time)";
  // instant: a short word in the header's one line; mission: the link's own line
  $("light-time").textContent = `${mission ? "light time" : "light"} ${clockText(c.one_way_light_time_s)}`;
  for (const id of ["next-pass", "next-uplink", "store-fill"]) $(id).hidden = !mission;
  if (mission) {
    showWindow("next-pass", "next pass", c.next_pass);
    showWindow("next-uplink", "uplink", c.next_uplink);
    showStore(c.store);
  }
  renderAge();
}

// ---- the Rover panel: how old its data is ------------------------------------------------

function renderAge() {
  const node = $("data-age");
  const mission = view.mode === "mission";
  node.hidden = !mission;
  $("readouts").classList.toggle("data-stale", false);
  if (!mission) return;
  const d = view.newest;
  if (!d) {
    node.textContent = "no data on the ground yet: it comes down in the next pass";
    node.dataset.stale = "false";
    return;
  }
  const now = view.nowT ?? d.t_s;
  const receivedAgo = d.received_t_s === null ? null : Math.max(0, now - d.received_t_s);
  const ageS = Math.max(0, now - d.t_s);
  const limitS = staleAfterS(view.comm && view.comm.plan, view.comm ? view.comm.one_way_light_time_s : 0);
  const stale = ageS > limitS;
  node.textContent = dataAgeText(d, receivedAgo);
  node.title = `the newest data on the ground is ${durationText(ageS)} old by the rover's clock`
    + (stale ? `: older than ${durationText(limitS)} (the relay's delay, the light time and a pass), stale` : "");
  node.dataset.stale = String(stale);
  node.dataset.ageS = String(Math.round(ageS));
  node.classList.toggle("stale-data", stale);
  $("readouts").classList.toggle("data-stale", stale);
}

// A frame that came down (received_t_s: across light time) is the newest data on the ground.
bus.on("frame", (f) => {
  if (!f || f.received_t_s === undefined || f.received_t_s === null) return;
  if (view.newest && f.t_s < view.newest.t_s) return;
  view.newest = { t_s: f.t_s, sol: f.sol, lmst_h: f.lmst_h, received_t_s: f.received_t_s };
  view.mode = "mission";
  renderAge();
});

bus.on("state", (s) => {
  if (s.rover !== view.rover) return;
  view.nowT = s.t_s;
  if (s.comm && s.comm !== view.mode) { view.mode = s.comm; load(); }
  if (view.comm) render();
});

bus.on("rover", (rover) => {
  Object.assign(view, { rover, comm: null, mode: null, nowT: null, newest: null });
  render();
  renderAge();
  load();
});

bus.on("start", () => {
  setInterval(() => { if (document.visibilityState === "visible") load(); }, POLL_MS);
  document.addEventListener("visibilitychange", () => { if (document.visibilityState === "visible") load(); });
});
