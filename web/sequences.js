// The Sequence part of the commanding panel: the editor with its live check, uploads of
// its text or of a file, each with its diagnostics beside what was sent, and the table of
// the rover's latest sequences.
import { api, detailText } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";

const view = { rover: null, validateTimer: null, diagnosticsTurn: 0 };

function showDiagnostics(result, list = $("validation")) {
  const items = [...(result.errors || []).map((d) => ["error", d]), ...(result.warnings || []).map((d) => ["warning", d])];
  list.replaceChildren(...items.map(([kind, d]) => {
    return el("li", { className: kind, textContent: `line ${d.line}:${d.column} ${kind} ${d.code}: ${d.message}` });
  }));
}

// A text the server did not check (413 over the upload limit, 429, no network) is not known
// to be valid: the editor's list says why, rather than an empty list that reads as valid.
function showNotChecked(r) {
  $("validation").replaceChildren(el("li", {
    className: r.status === 413 ? "error" : "warning",
    textContent: `not checked (${r.status || "not sent"}): ${detailText(r)}`,
  }));
}

// The editor's list describes the editor's text (its live check, or its upload); it shows
// the latest answer: a check that returns after an upload of the text (or a newer check)
// was asked for is not shown over it.
async function validateEditor() {
  const turn = ++view.diagnosticsTurn;
  const text = $("editor").value;
  if (!text.trim()) { $("validation").replaceChildren(); return; }
  const r = await api(`/api/sequences/validate?rover=${view.rover}`, {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ text }),
  });
  if (turn !== view.diagnosticsTurn) return;
  if (r.ok && r.body) showDiagnostics(r.body);
  else showNotChecked(r);
}

function uploadStarts() {
  clearTimeout(view.validateTimer);
  view.diagnosticsTurn++;
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
  const r = await api(`/api/rovers/${view.rover}/sequences`, {
    method: "POST", headers: { "Content-Type": "application/json" },
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
  uploaded(await api(`/api/rovers/${view.rover}/sequences`, { method: "POST", body: form }), file.name);
}

async function refreshSequences() {
  if (!view.rover) return;
  const r = await api(`/api/rovers/${view.rover}/sequences`);
  if (!r.ok) return;
  const body = $("sequences").querySelector("tbody");
  body.replaceChildren(...r.body.slice(0, 12).map((s) => el("tr", {},
    ...[s.id, s.name, s.submitted_by || "", s.status, s.detail || ""].map((v) => el("td", { textContent: v })))));
}

bus.on("rover", (rover) => { view.rover = rover; refreshSequences(); });
bus.on("sequences-changed", refreshSequences);
bus.on("start", () => {
  $("editor").addEventListener("input", () => {
    clearTimeout(view.validateTimer);
    view.validateTimer = setTimeout(validateEditor, 300);
  });
  $("upload-text").addEventListener("click", uploadText);
  $("upload-file").addEventListener("click", uploadFile);
  $("file").addEventListener("change", () => { $("file-result").hidden = true; }); // another file
  setInterval(refreshSequences, 3000);
});
