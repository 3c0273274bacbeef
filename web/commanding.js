// The Immediate command part of the commanding panel.
import { api, detailText } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $, el } from "./lib/dom.js";

const view = { rover: null, dictionary: [] };

// The immediate-command form, built from the command dictionary the server publishes: each
// argument's kind, unit, range and note come from the spec the server validates with, so a
// value out of range is caught here, named with the range the server would quote, before
// anything is sent. Rules across arguments (a note says them) are left to the server.
function currentCommand() { return view.dictionary.find((c) => c.command === $("command").value); }

function argHint(a) {
  const parts = [a.range || a.type.replaceAll("_", " ")];
  if (!a.required) parts.push(a.default === null ? "optional" : `default ${a.default}`);
  if (a.note) parts.push(a.note);
  return `${a.name}: ${parts.join("; ")}`;
}

function argInput(a) {
  let input;
  if (a.type === "boolean") {
    input = el("select");
    input.append(new Option(a.required ? `${a.name}?` : `${a.name} (default)`, ""),
      new Option("true", "true"), new Option("false", "false"));
  } else {
    input = el("input");
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
    return el("label", { className: "arg" }, argInput(a),
      a.unit ? el("span", { className: "unit", textContent: a.unit }) : null);
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
  const r = await api(`/api/rovers/${view.rover}/commands`, {
    method: "POST", headers: { "Content-Type": "application/json" },
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
  bus.emit("sequences-changed");
}

bus.on("rover", (rover) => { view.rover = rover; });
bus.on("start", async () => {
  view.dictionary = (await api("/api/commands")).body || [];
  $("command").replaceChildren(...view.dictionary.map((c) => new Option(c.command, c.command)));
  $("command").addEventListener("change", renderArgs);
  $("send").addEventListener("click", sendCommand);
  renderArgs();
});
