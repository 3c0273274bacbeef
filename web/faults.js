// The Faults panel (server/faults, docs/DESIGN.md "Faults and training"): the test
// conductor injects a fault into the simulated rover (truth side only: the rover reports
// only what its sensors then measure), now or at a UTC time; lists the rover's faults,
// pending, applied or failed; and reveals them, after which every reader sees them on the
// sol timeline for the debrief. Shown only to the conductor role and above, holding this
// tab's token (the routes need it). Talks to the other panels through the event bus only.
import { api, detailText, heldToken } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";
import { lmstText } from "./lib/marstime.js";
import { mayAct } from "./lib/roles.js";

const AXES = ["x", "y", "z"];
// Each kind's parameters (sim/faults/records.py: the server checks them; a 422 says why).
const KINDS = {
  gyro_bias: [["axis", AXES], ["bias_deg_per_h", "deg/h"]],
  accel_bias: [["axis", AXES], ["bias_ug", "µg"]],
  navcam: [],
  pancam_dust: [["tau", "optical depth, 0 to 10"]],
  hga_stuck: [],
  wheel: [["wheel", ["LF", "LM", "LR", "RF", "RM", "RR"]], ["mode", ["fail", "stall"]]],
  sand_trap: [["x_m", "m North of the start"], ["y_m", "m East of the start"], ["radius_m", "m"]],
};
const LIST_EVERY_MS = 2000; // the list is read again at most this often while shown

const panel = { rover: null, shown: false, listedAt: 0 };

function faultsPath() {
  return `/api/rovers/${encodeURIComponent(panel.rover)}/faults`;
}

function say(text, bad = false) {
  const out = $("fault-status");
  out.textContent = text;
  out.className = bad ? "fault-status bad" : "fault-status";
}

function showParameters() {
  const kind = $("fault-kind").value;
  $("fault-params").replaceChildren(...KINDS[kind].map(([name, spec]) => {
    const input = Array.isArray(spec)
      ? el("select", {}, ...spec.map((v) => new Option(v, v)))
      : el("input", { type: "number", step: "any", placeholder: spec });
    input.dataset.testid = `fault-param-${name}`;
    input.dataset.name = name;
    input.dataset.number = Array.isArray(spec) ? "" : "1";
    return el("label", {}, `${name} `, input);
  }));
}

function body() {
  const parameters = {};
  for (const input of $("fault-params").querySelectorAll("[data-name]")) {
    const text = input.value.trim();
    if (text === "") continue; // missing: the server names it
    parameters[input.dataset.name] = input.dataset.number ? Number(text) : text;
  }
  const out = { kind: $("fault-kind").value, parameters };
  const at = $("fault-at-utc").value.trim();
  if (at) out.at_utc = at;
  return out;
}

async function inject() {
  const r = await api(faultsPath(), {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body()),
  });
  if (!r.ok) { say(`not injected: ${detailText(r)}`, true); return; }
  say(`fault #${r.body.fault_id} injected: ${r.body.description}, due sol ${r.body.at.sol} ${lmstText(r.body.at.lmst_h)} LMST`);
  await list();
}

async function reveal() {
  const r = await api(`${faultsPath()}/reveal`, { method: "POST" });
  if (!r.ok) { say(`not revealed: ${detailText(r)}`, true); return; }
  say(`${r.body.revealed} fault${r.body.revealed === 1 ? "" : "s"} revealed: every reader sees them on the timeline`);
  showList(r.body.faults);
}

function when(w) {
  return w ? `sol ${w.sol} ${lmstText(w.lmst_h)}` : "—";
}

function showList(faults) {
  $("fault-list").replaceChildren(...faults.map((f) => {
    const row = el("tr", { title: f.error || "" },
      el("td", { textContent: `#${f.fault_id}` }),
      el("td", { textContent: f.description }),
      el("td", { textContent: when(f.at) }),
      el("td", { textContent: when(f.applied) }),
      el("td", { textContent: f.state, className: `fault-${f.state}` }),
      el("td", { textContent: f.revealed ? "revealed" : "hidden" }));
    row.dataset.testid = "fault-row";
    row.dataset.state = f.state;
    row.dataset.revealed = f.revealed ? "1" : "";
    return row;
  }));
  $("fault-empty").hidden = faults.length > 0;
}

async function list() {
  if (!panel.shown || !panel.rover) return;
  panel.listedAt = Date.now();
  const r = await api(faultsPath());
  if (r.ok) showList(r.body.faults);
  else say(`cannot list the faults: ${detailText(r)}`, true);
}

function onMe(me) {
  panel.shown = mayAct(me, heldToken(), "conductor");
  $("faults-panel").hidden = !panel.shown;
  if (panel.shown) list();
}

function start() {
  $("fault-kind").replaceChildren(...Object.keys(KINDS).map((k) => new Option(k, k)));
  $("fault-kind").addEventListener("change", showParameters);
  $("fault-inject").addEventListener("click", inject);
  $("fault-reveal").addEventListener("click", reveal);
  showParameters();
  bus.on("me", onMe);
  bus.on("rover", (rover) => { panel.rover = rover; list(); });
  bus.on("state", () => { if (Date.now() - panel.listedAt >= LIST_EVERY_MS) list(); });
}

start();
