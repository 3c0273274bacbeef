// The console's rehearsals (server.rehearsal, issue 25): a sequence run many times over what
// the ground does not know before it goes up, and the odds of each line.
// - In the sequence editor, an operator's Rehearse controls (hidden from other roles): the
//   editor's text or an uploaded sequence, runs and seed checked here (web/lib/rehearsal.js),
//   POST /api/rovers/{rover}/rehearsals; the server's refusal said as it says it (a sequence
//   that does not validate lists its errors at their lines).
// - The Rehearsals panel: the open campaign's progress bar (runs done of total, ETA), read by
//   polling GET .../rehearsals/{id} about once a second while it runs (at once on a
//   "rehearsal" notice, if the server sends one), stopped when it is done, cancelled or failed
//   or the campaign is closed; Cancel; when done, the risk table, one row per line, its
//   verdict coloured; "Predicted vs executed" (GET .../{id}/report), each executed figure's
//   percentile, what fell outside 95 % flagged, the truth part only when the server gave it
//   (the truth view). The rover's past campaigns below, newest first; a click opens one.
// - An operator's console has the rover's 3D view draw the finished campaign it shows.
// - The campaign shown goes to the bus ("rehearsal": {rover, summary, risk}) for the
//   timeline's Rehearsal lane (timeline/rehearsal.js).
import { api, detailText, heldToken } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";
import {
  aqfText, byName, ellipseText, finished, p95Text, parseRequest, pct, progress, rangeText,
  reportRows, requestBody, utcText, whenText,
} from "./lib/rehearsal.js";
import { mayAct } from "./lib/roles.js";

const POLL_MS = 1000; // the summary read again this often while a campaign runs
const LIST_SHOWN = 20;
const view = {
  rover: null, me: null, open: null, summary: null, poll: null, turn: 0, ref: null, list: [], drawn: -1,
};

const base = () => `/api/rovers/${encodeURIComponent(view.rover)}/rehearsals`;
const post = (path, body) => api(path, {
  method: "POST", headers: { "Content-Type": "application/json" }, body: body ?? "{}",
});

// ---- starting a campaign --------------------------------------------------------------

function say(text, bad = false) {
  const status = $("rehearse-status");
  status.textContent = text;
  status.classList.toggle("bad", bad);
}

// A 400's errors at their lines, whatever list the server put them in.
function errorsOf(body) {
  const detail = body && body.detail;
  const list = (body && body.errors) || (detail && typeof detail === "object" && !Array.isArray(detail) && detail.errors);
  return Array.isArray(list) ? list : [];
}

function showErrors(errors) {
  $("rehearse-errors").replaceChildren(...errors.map((d) => el("li", {
    className: "error",
    textContent: d.line !== undefined
      ? `line ${d.line}${d.column !== undefined ? `:${d.column}` : ""} error${d.code ? ` ${d.code}` : ""}: ${d.message ?? JSON.stringify(d)}`
      : (d.message || JSON.stringify(d)),
  })));
}

async function rehearse() {
  showErrors([]);
  const request = parseRequest($("rehearse-runs").value, $("rehearse-seed").value);
  if (request.error) { say(request.error, true); return; }
  const which = $("rehearse-what").value;
  const what = which ? { id: Number(which) } : { text: $("editor").value };
  if (!which && !what.text.trim()) { say("The editor is empty: write a sequence to rehearse", true); return; }
  say("Asking the server…");
  const r = await post(base(), requestBody(what, request.runs, request.seed));
  if (!r.ok) {
    const errors = errorsOf(r.body);
    showErrors(errors);
    const detail = r.body && r.body.detail;
    const said = typeof detail === "string" ? detail
      : detail && typeof detail.message === "string" ? detail.message
      : errors.length ? `the sequence has ${errors.length} error(s)` : detailText(r);
    say(`Not rehearsed (${r.status || "not sent"}): ${said}`, true);
    return;
  }
  say(`Rehearsal #${r.body.id} started: ${r.body.runs} runs, seed ${r.body.seed}`);
  openCampaign(r.body);
  loadList();
}

async function fillWhat() {
  if (!view.rover) return;
  const r = await api(`/api/rovers/${encodeURIComponent(view.rover)}/sequences`);
  if (!r.ok) return;
  const select = $("rehearse-what");
  const kept = select.value;
  select.replaceChildren(new Option("the editor's text", ""),
    ...r.body.slice(0, 12).map((s) => new Option(`#${s.id} ${s.name} (${s.status})`, String(s.id))));
  if ([...select.options].some((o) => o.value === kept)) select.value = kept;
}

// ---- the open campaign ----------------------------------------------------------------

function stopPolling() {
  clearTimeout(view.poll);
  view.poll = null;
}

function openCampaign(summary) {
  stopPolling();
  const turn = ++view.turn; // a campaign opened later makes this one's answers stale
  view.open = summary.id;
  $("rehearsal-campaign").hidden = false;
  $("rehearsal-close").hidden = false;
  $("rehearsal-report").hidden = true;
  $("rehearsal-report-status").textContent = "";
  $("rehearsal-3d").textContent = "";
  $("risk-table").querySelector("tbody").replaceChildren();
  $("risk-table").hidden = true;
  showSummary(summary, null);
  read(turn);
}

function closeCampaign() {
  stopPolling();
  view.turn++;
  view.open = null;
  view.summary = null;
  $("rehearsal-campaign").hidden = true;
  $("rehearsal-close").hidden = true;
  $("rehearsal-panel").dataset.state = "";
  markListed();
}

async function read(turn) {
  view.poll = null;
  const r = await api(`${base()}/${view.open}`);
  if (turn !== view.turn) return;
  if (!r.ok) {
    $("rehearsal-words").textContent = `Could not read rehearsal #${view.open}: ${detailText(r)}`;
  } else {
    showSummary(r.body, r.body.risk);
    if (finished(r.body.state)) { loadList(); return; }
  }
  view.poll = setTimeout(() => read(turn), POLL_MS);
}

function showSummary(summary, risk) {
  view.summary = summary;
  const panel = $("rehearsal-panel");
  panel.dataset.state = summary.state;
  panel.dataset.campaign = String(summary.id);
  const { fraction, words } = progress(summary);
  const bar = $("rehearsal-bar");
  bar.style.width = `${(100 * fraction).toFixed(1)}%`;
  bar.className = `rehearsal-bar state-${summary.state}`;
  bar.parentElement.setAttribute("aria-valuenow", String(summary.done || 0));
  bar.parentElement.setAttribute("aria-valuemax", String(summary.runs || 0));
  $("rehearsal-words").textContent = words;
  $("rehearsal-title").textContent = `#${summary.id}`;
  const what = summary.sequence_id !== null && summary.sequence_id !== undefined
    ? `sequence #${summary.sequence_id}` : "the editor's text";
  const warm = Number.isFinite(summary.warmup_s) ? ` · workers warmed up in ${summary.warmup_s.toFixed(1)} s` : "";
  $("rehearsal-about").textContent = `Rehearsal #${summary.id} of ${what} by ${summary.user}, `
    + `${summary.runs} runs, seed ${summary.seed}, started ${utcText(summary.created_t_utc)}${warm}`;
  $("rehearsal-cancel").hidden = finished(summary.state);
  markListed();
  if (risk) showRisk(risk);
  if (summary.state === "done" && risk) {
    bus.emit("rehearsal", { rover: view.rover, summary, risk });
    if (view.drawn !== view.turn) { view.drawn = view.turn; drawIn3d(summary.id); }
  }
}

// The 3D view is shared by every viewer of the rover: an operator's console has it draw the
// campaign it shows (POST .../scene/rehearsal); otherwise it shows the newest finished one.
async function drawIn3d(id) {
  const note = $("rehearsal-3d");
  if (!mayAct(view.me, Boolean(heldToken()), "operator")) { note.textContent = ""; return; }
  const r = await post(`/api/rovers/${encodeURIComponent(view.rover)}/scene/rehearsal`, JSON.stringify({ id }));
  if (id !== view.open) return;
  note.textContent = r.ok && r.body.rehearsal
    ? `3D view: the predicted traverses and the 50 % and 95 % end ellipses of ${r.body.rehearsal.note}`
    : `Not drawn in the 3D view: ${detailText(r)}`;
}

async function cancel() {
  const id = view.open;
  const r = await post(`${base()}/${id}/cancel`);
  if (id !== view.open) return;
  if (!r.ok) { $("rehearsal-words").textContent = `Not cancelled: ${detailText(r)}`; return; }
  stopPolling();
  showSummary(r.body, null);
  loadList();
}

// ---- the risk table ---------------------------------------------------------------------

const deg = (v) => `${v.toFixed(1)}°`;
const secs = (v) => `${Math.round(v)} s`;

function verdictCell(line) {
  const why = (line.why || []).join("; ");
  return el("td", {},
    el("span", { className: `verdict verdict-${line.verdict}`, textContent: line.verdict, dataset: { testid: "risk-verdict" } }),
    why ? el("div", { className: "risk-why", textContent: why }) : null);
}

function riskRow(line) {
  const cells = [
    String(line.line),
    line.command,
    null, // the verdict's own cell
    byName(line.halts),
    byName(line.keepouts),
    ellipseText(line.end_true && line.end_true.ellipse_95),
    p95Text(line.max_tilt_deg, 1, "°"),
    aqfText(line.aqf),
    rangeText(line.imu_integration_s, secs),
    line.hga_margin_deg ? rangeText(line.hga_margin_deg, deg) : "—",
    line.end_t_s ? whenText(line.end_t_s.p50, view.ref) : "—",
  ];
  const row = el("tr", { className: `risk-${line.verdict}`, dataset: { testid: "risk-row", line: String(line.line), verdict: line.verdict } });
  row.append(...cells.map((text, i) => (i === 2 ? verdictCell(line)
    : el("td", { textContent: text, className: i === 1 ? "risk-command" : i >= 5 && i <= 9 && i !== 7 ? "nowrap" : "" }))));
  const done = line.status ? `completed in ${pct(line.status.completed)} of runs` : "";
  row.title = `line ${line.line}: ${done}`;
  return row;
}

function showRisk(risk) {
  const table = $("risk-table");
  table.querySelector("tbody").replaceChildren(...(risk.lines || []).map(riskRow));
  table.hidden = false;
  const end = risk.end_t_s;
  $("risk-end").textContent = end
    ? `${risk.runs} runs gathered · the sequence ends at ${whenText(end.p50, view.ref)} (5–95 %: `
      + `${whenText(end.p5, view.ref)} to ${whenText(end.p95, view.ref)})`
    : `${risk.runs} runs gathered`;
}

// ---- predicted against executed ---------------------------------------------------------

function reportTable(lines, testid) {
  const rows = reportRows(lines, view.ref);
  return el("table", { className: "report-table", dataset: { testid } },
    el("thead", {}, el("tr", {}, ...["line", "figure", "executed", "where in the prediction", ""].map((t) => el("th", { textContent: t })))),
    el("tbody", {}, ...rows.map((r) => el("tr", {
      className: r.outside ? "outside" : "",
      dataset: { testid: "report-row", line: String(r.line), figure: r.name, outside: r.outside ? "1" : "0" },
    }, el("td", { textContent: String(r.line), title: r.command }), el("td", { textContent: r.words }),
    el("td", { textContent: r.executed }), el("td", { textContent: r.place }),
    el("td", { className: "flag", textContent: r.outside ? "outside 95 %" : "" })))));
}

async function askReport() {
  const id = view.open;
  $("rehearsal-report-status").textContent = "Asking…";
  const r = await api(`${base()}/${id}/report`);
  if (id !== view.open) return;
  const box = $("rehearsal-report");
  if (!r.ok) {
    box.hidden = true;
    $("rehearsal-report-status").textContent = `No report (${r.status || "not sent"}): ${detailText(r)}`;
    return;
  }
  const report = r.body;
  const flags = report.flags || [];
  $("rehearsal-report-status").textContent = flags.length
    ? `${flags.length} figure(s) outside the predicted 95 %` : "every figure inside the predicted 95 %";
  const parts = [
    el("ul", { className: "report-flags", dataset: { testid: "report-flags" } },
      ...flags.map((f) => el("li", { textContent: f }))),
    reportTable(report.lines, "report-table"),
  ];
  if (report.truth) {
    parts.push(el("h3", {}, "Against the truth ", el("span", { className: "truth-tag", textContent: "truth view" })),
      reportTable(report.truth.lines, "report-truth"));
  }
  box.replaceChildren(...parts);
  box.hidden = false;
}

// ---- the rover's campaigns --------------------------------------------------------------

function markListed() {
  for (const row of $("rehearsal-list").querySelectorAll("tbody tr")) {
    row.classList.toggle("open", row.dataset.id === String(view.open));
  }
}

async function loadList() {
  if (!view.rover) return;
  const rover = view.rover;
  const r = await api(base());
  if (rover !== view.rover) return;
  const body = $("rehearsal-list").querySelector("tbody");
  if (!r.ok) { $("rehearsal-empty").textContent = `Could not list the rehearsals: ${detailText(r)}`; return; }
  view.list = r.body;
  $("rehearsal-empty").textContent = r.body.length ? "" : "No rehearsals yet for this rover.";
  body.replaceChildren(...r.body.slice(0, LIST_SHOWN).map((s) => {
    const row = el("tr", { dataset: { testid: "rehearsal-listed", id: String(s.id), state: s.state }, tabIndex: 0 },
      ...[`#${s.id}`, utcText(s.created_t_utc), s.user,
        s.sequence_id !== null && s.sequence_id !== undefined ? `sequence #${s.sequence_id}` : "editor text",
        `${s.done} / ${s.runs}`, s.state, String(s.seed)].map((t) => el("td", { textContent: t })));
    row.addEventListener("click", () => openCampaign(s));
    row.addEventListener("keydown", (e) => { if (e.key === "Enter") openCampaign(s); });
    return row;
  }));
  markListed();
}

// ---- roles and start ----------------------------------------------------------------------

function showControls() {
  const may = mayAct(view.me, Boolean(heldToken()), "operator");
  $("rehearse-controls").hidden = !may;
  $("rehearsal-cancel").disabled = !may;
}

bus.on("me", (me) => { view.me = me; showControls(); });
bus.on("rover", (rover) => {
  view.rover = rover;
  closeCampaign();
  loadList();
  fillWhat();
});
bus.on("state", (s) => {
  if (s.frame) view.ref = { t_s: s.frame.t_s, sol: s.frame.sol, lmst_h: s.frame.lmst_h };
});
bus.on("sequences-changed", fillWhat);
bus.on("notice", (n) => { // a server that tells of progress: read at once
  if (n.type !== "rehearsal" || !view.open || (n.rehearsal && n.rehearsal.id !== view.open)) return;
  if (view.poll) { stopPolling(); read(view.turn); }
});
bus.on("start", () => {
  $("rehearse").addEventListener("click", rehearse);
  $("rehearse-what").addEventListener("focus", fillWhat);
  $("rehearsal-cancel").addEventListener("click", cancel);
  $("rehearsal-close").addEventListener("click", closeCampaign);
  $("rehearsal-report-ask").addEventListener("click", askReport);
  $("rehearsal-refresh").addEventListener("click", loadList);
  showControls();
});
