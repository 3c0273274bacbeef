// A rehearsal's figures as the console writes them (web/rehearsal.js draws them): the
// campaign's request checked before it is sent, its progress, the risk table's cells
// (server.rehearsal.risk: percentiles over the runs in which a step ran, ellipses as the
// semi-axes of a Gaussian fit, chi2 with 2 degrees of freedom) and the predicted-vs-executed
// report's rows (server.rehearsal.compare). Pure functions: tests/js/rehearsal.test.mjs.
import { lmstAt, lmstText } from "./marstime.js";

export const MAX_RUNS = 1000;
export const DEFAULT_RUNS = 100;
export const MAX_SEED = 2n ** 63n - 1n; // the seed is a 64-bit signed integer's range
export const TERMINAL = ["done", "cancelled", "failed"];

/** Whether a campaign's state is final (its polling stops). */
export const finished = (state) => TERMINAL.includes(state);

/**
 * The request's runs and seed from the inputs' text: {runs, seed} (the seed as a string of
 * digits: 2**63 - 1 is past a double's exact integers), or {error} saying what is wrong.
 * An empty runs field is the server's default (100), an empty seed 0.
 */
export function parseRequest(runsText, seedText) {
  const runsRaw = String(runsText ?? "").trim();
  const seedRaw = String(seedText ?? "").trim();
  const runs = runsRaw === "" ? DEFAULT_RUNS : Number(runsRaw);
  if (!/^\d*$/.test(runsRaw) || !Number.isInteger(runs) || runs < 1 || runs > MAX_RUNS) {
    return { error: `runs must be a whole number from 1 to ${MAX_RUNS}, not "${runsRaw}"` };
  }
  const seed = seedRaw === "" ? "0" : seedRaw;
  if (!/^\d+$/.test(seed) || BigInt(seed) > MAX_SEED) {
    return { error: `seed must be a whole number from 0 to 2^63 - 1, not "${seedRaw}"` };
  }
  return { runs, seed: BigInt(seed).toString() };
}

/** The POST body's JSON: the editor's text (what.text) or a stored sequence (what.id), the
 * seed written as its digits (JSON has no limit on an integer's size; JSON.stringify of a
 * Number would round it). */
export function requestBody(what, runs, seed) {
  const head = what.id !== undefined && what.id !== null
    ? `"sequence_id": ${Number(what.id)}` : `"sequence_text": ${JSON.stringify(what.text)}`;
  return `{${head}, "runs": ${runs}, "seed": ${seed}}`;
}

/** A duration as people say it: "45 s", "3 min 05 s", "1 h 02 min". */
export function durationText(s) {
  if (s === null || s === undefined || !Number.isFinite(s)) return "—";
  const t = Math.max(0, Math.round(s));
  if (t < 60) return `${t} s`;
  const two = (n) => String(n).padStart(2, "0");
  if (t < 3600) return `${Math.floor(t / 60)} min ${two(t % 60)} s`;
  return `${Math.floor(t / 3600)} h ${two(Math.floor((t % 3600) / 60))} min`;
}

/** A campaign summary's progress: the bar's fraction (0..1) and its words. */
export function progress(summary) {
  const total = Math.max(1, summary.runs || 0);
  const done = Math.min(total, Math.max(0, summary.done || 0));
  const fraction = summary.state === "done" ? 1 : done / total;
  let words = `${done} / ${total} runs`;
  if (summary.state === "queued") words += " · queued";
  else if (summary.state === "running") {
    words += summary.eta_s === null || summary.eta_s === undefined
      ? " · ETA once the first runs are in" : ` · ETA ${durationText(summary.eta_s)}`;
  } else words += ` · ${summary.state}`;
  if (summary.state === "failed" && summary.error) words += `: ${summary.error}`;
  return { fraction, words };
}

const NBSP = "\u00a0"; // a figure and its unit are not split across lines

/** A probability as a percentage: "0 %", "<1 %" (above 0, under one half of a per cent),
 * "6 %", "99 %" (a no-break space before the sign); "—" when unknown. */
export function pct(p) {
  if (p === null || p === undefined || !Number.isFinite(p)) return "—";
  const v = 100 * p;
  if (v > 0 && v < 0.5) return `<1${NBSP}%`;
  if (v < 100 && v > 99.5) return `>99${NBSP}%`;
  return `${Math.round(v)}${NBSP}%`;
}

/** Probabilities by name ({tilt: 0.03, slip: 0.02}), the likeliest first, zeros left out:
 * "tilt 3 %, slip 2 %", or "none" when all are zero (or there are none). */
export function byName(probs) {
  const items = Object.entries(probs || {}).filter(([, p]) => p > 0).sort((a, b) => b[1] - a[1]);
  return items.length ? items.map(([k, p]) => `${k}${NBSP}${pct(p)}`).join(", ") : "none";
}

/** A 2-D ellipse's semi-axes and the major axis' bearing (from North towards East):
 * "0.42 × 0.18 m, 35°"; "—" when none. The bearing is taken into [0, 180)°: an axis, not
 * a direction. */
export function ellipseText(e, digits = 2) {
  if (!e) return "—";
  const angle = ((Math.round(e.angle_deg) % 180) + 180) % 180;
  return `${e.a_m.toFixed(digits)} × ${e.b_m.toFixed(digits)} m, ${angle}°`;
}

/** A percentile dict's p95 with its unit ("4.2°"), or "—" (the step never ran). */
export function p95Text(d, digits, unit) {
  return d && Number.isFinite(d.p95) ? `${d.p95.toFixed(digits)}${unit}` : "—";
}

/** A p5–p95 range with its median: "12 s (8–20)"; "—" when none. */
export function rangeText(d, format) {
  if (!d || !Number.isFinite(d.p50)) return "—";
  return `${format(d.p50)} (${format(d.p5)}–${format(d.p95)})`;
}

/** The likeliest AQF at a step's end with its share: "Fine 90 %" (others in order after). */
export function aqfText(aqf) {
  const items = Object.entries(aqf || {}).filter(([, p]) => p > 0).sort((a, b) => b[1] - a[1]);
  return items.length ? items.map(([k, p]) => `${k}${NBSP}${pct(p)}`).join(", ") : "—";
}

/** Where a figure of the executed run falls: "37th percentile" (ordinal, rounded). */
export function ordinal(n) {
  const k = Math.round(n);
  const tens = k % 100;
  const suffix = tens >= 11 && tens <= 13 ? "th" : ({ 1: "st", 2: "nd", 3: "rd" }[k % 10] || "th");
  return `${k}${suffix}`;
}

const FIGURE_WORDS = {
  end_t_s: "end time",
  imu_integration_s: "IMU time",
  position_sigma_m: "position σ",
  hga_margin_predicted_deg: "HGA margin (rover)",
  end_est: "end pose (estimate)",
  end_true: "end pose (truth)",
  status: "status",
  max_tilt_true_deg: "max tilt (truth)",
  heading_est_deg: "heading (estimate)",
  aqf: "AQF",
  hga_margin_deg: "HGA margin (truth)",
};

const FIGURE_UNITS = { _s: " s", _m: " m", _deg: "°" }; // by the name's ending (SI and degrees)

/** What the executed figure was, in words: a time (``..._t_s``) as sol and LMST when `ref`
 * is known, a pose as its mission position, a number with the unit its name ends with. */
export function executedText(figure, ref = null) {
  const x = figure.executed;
  if (x === null || x === undefined) return "—";
  if (Array.isArray(x)) return `(${x.map((v) => v.toFixed(2)).join(", ")}) m`;
  if (typeof x === "number" && figure.name.endsWith("_t_s") && ref) return whenText(x, ref);
  if (typeof x === "number") {
    const unit = Object.entries(FIGURE_UNITS).find(([end]) => figure.name.endsWith(end));
    return `${Number.isInteger(x) ? String(x) : x.toFixed(2)}${unit ? unit[1] : ""}`;
  }
  return String(x);
}

/** Where it fell in the prediction, in words: a percentile, a pose's Mahalanobis distance
 * squared with its percentile, a status's predicted probability. */
export function placeText(figure) {
  if (figure.probability !== undefined && figure.probability !== null) {
    return `predicted ${pct(figure.probability)}`;
  }
  const parts = [];
  if (figure.percentile !== undefined && figure.percentile !== null) parts.push(`${ordinal(figure.percentile)} percentile`);
  if (figure.mahalanobis2 !== undefined && figure.mahalanobis2 !== null) parts.push(`d² ${figure.mahalanobis2.toFixed(2)}`);
  return parts.length ? parts.join(", ") : "—";
}

/** The report's rows, one per figure of each line: {line, command, name, words, executed,
 * place, outside}; times as sol and LMST from `ref` ({t_s, sol, lmst_h}) when given. */
export function reportRows(lines, ref = null) {
  return (lines || []).flatMap((l) => (l.figures || []).map((f) => ({
    line: l.line,
    command: l.command || "",
    name: f.name,
    words: FIGURE_WORDS[f.name] || f.name.replaceAll("_", " "),
    executed: executedText(f, ref),
    place: placeText(f),
    outside: Boolean(f.outside_95),
  })));
}

/** A risk line's predicted band on the timeline: the step's start from its p5 to its end's
 * p95 (the outer band) and its median start to median end (the inner), TT seconds; null
 * when the step never ran in any run. */
export function predictedBand(line) {
  const s = line.start_t_s, e = line.end_t_s;
  if (!s || !e || !Number.isFinite(s.p5) || !Number.isFinite(e.p95)) return null;
  return { outer: [s.p5, e.p95], inner: [s.p50, Math.max(s.p50, e.p50)] };
}

/** A TT time as the console says it, "sol 3 13:02:11 LMST", counted from a moment of known
 * sol and LMST (`ref`: {t_s, sol, lmst_h}, the rover's latest frame); "—" without either. */
export function whenText(t_s, ref) {
  if (!ref || t_s === null || t_s === undefined || !Number.isFinite(t_s)) return "—";
  const h = lmstAt(t_s, ref);
  return `sol ${ref.sol + Math.floor(h / 24)} ${lmstText(h)} LMST`;
}

const words = (s) => String(s || "").trim().split(/\s+/).join(" ");

/**
 * The predicted bands of a rehearsal's lines as the timeline draws them beside the executed
 * steps: [{line, command, verdict, outer: [t0, t1], inner: [t0, t1]}], TT seconds. The
 * rehearsal predicts from the last state reported before it: when its sequence has run
 * (`commands`, the sol's executed steps {sequence_id, step_index, command, start: {t_s}}),
 * the bands are moved by the time between the predicted median start of its first line and
 * the executed start of that step. The executed sequence is the campaign's sequence id, or
 * else the newest whose first step's command is the first line's.
 */
export function timelineBands(summary, risk, commands) {
  const lines = (risk && risk.lines) || [];
  const bands = lines.map((l) => ({ line: l.line, command: l.command, verdict: l.verdict, ...predictedBand(l) }))
    .filter((b) => b.outer);
  if (!bands.length) return { bands, shift_s: 0, sequence_id: null };
  const firsts = (commands || []).filter((c) => c.step_index === 0 && c.sequence_id !== null && c.sequence_id !== undefined);
  const known = summary && summary.sequence_id !== null && summary.sequence_id !== undefined;
  const matching = firsts.filter((c) => (known ? c.sequence_id === summary.sequence_id
    : words(c.command) === words(lines[0].command)));
  const executed = matching.sort((a, b) => b.sequence_id - a.sequence_id || b.start.t_s - a.start.t_s)[0];
  const first = lines[0].start_t_s;
  if (!executed || !first || !Number.isFinite(first.p50)) return { bands, shift_s: 0, sequence_id: null };
  const shift = executed.start.t_s - first.p50;
  const moved = (pair) => pair.map((t) => t + shift);
  return {
    bands: bands.map((b) => ({ ...b, outer: moved(b.outer), inner: moved(b.inner) })),
    shift_s: shift,
    sequence_id: executed.sequence_id,
  };
}

/** A stored UTC time ("2026-12-05T04:58:37.174705+00:00") as "2026-12-05 04:58:37 UTC";
 * "—" for none; a text not in that form as it is. */
export function utcText(iso) {
  if (!iso) return "—";
  const m = /^(\d{4}-\d\d-\d\d)[T ](\d\d:\d\d:\d\d)/.exec(String(iso));
  return m ? `${m[1]} ${m[2]} UTC` : String(iso);
}
