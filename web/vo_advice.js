// The VO pointing advice for the drive line under the editor's caret (POST
// /api/rovers/{rover}/vo-advice, server.terrain.advice_api): the recommended Navcam pointing
// and why, and on request the pointing put into that line (web/lib/pointing.js).
import { api, detailText } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";
import { lineAt, textWithPointing } from "./lib/pointing.js";

const view = { rover: null, line: null, args: null };

const pct = (x) => `${Math.round(100 * x)} %`;

function show(r, line) {
  const out = $("vo-advice");
  view.line = null;
  view.args = null;
  $("vo-advice-apply").hidden = true;
  if (!r.ok || !r.body) {
    out.textContent = `No advice for line ${line} (${r.status || "not sent"}): ${detailText(r)}`;
    return;
  }
  const b = r.body;
  const best = b.recommended;
  const head = best
    ? `Line ${line}: point the Navcams at az ${best.az_deg}°, el ${best.el_deg}° — ` +
      `${Math.round(best.features_min)} trackable features at the worst of ${b.pairs - 1} steps, ` +
      `overlap ≥ ${pct(best.overlap_min)}, shadow ≤ ${pct(best.shadow_max)}`
    : `Line ${line}: no pointing recommended — ${b.reason}`;
  out.replaceChildren(
    el("span", { textContent: head }),
    el("br"),
    el("small", { textContent: `Rule: ${b.rule}. Map: ${b.map}.` }),
  );
  if (best) {
    view.line = line;
    view.args = b.arguments;
    $("vo-advice-apply").textContent = `Put ${b.arguments} into line ${line}`;
    $("vo-advice-apply").hidden = false;
  }
}

async function askAdvice() {
  const editor = $("editor");
  const line = lineAt(editor.value, editor.selectionStart);
  $("vo-advice").textContent = `Asking for line ${line}…`;
  const r = await api(`/api/rovers/${view.rover}/vo-advice`, {
    method: "POST", headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ text: editor.value, line }),
  });
  show(r, line);
}

// The editor's text changes like a typed edit: its live check runs on it.
function applyAdvice() {
  if (view.line === null) return;
  const editor = $("editor");
  editor.value = textWithPointing(editor.value, view.line, view.args);
  editor.dispatchEvent(new Event("input"));
  $("vo-advice-apply").hidden = true;
}

bus.on("rover", (rover) => { view.rover = rover; });
bus.on("start", () => {
  $("vo-advice-ask").addEventListener("click", askAdvice);
  $("vo-advice-apply").addEventListener("click", applyAdvice);
});
