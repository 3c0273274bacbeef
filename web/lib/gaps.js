// Telemetry with holes (issue 23): across light time the ground has what has come down,
// highest priority first, and the onboard store reports what it dropped. A plot must not
// draw a line across data it does not have: these functions say where the holes are, and
// the plots put a break (a point with no value) there. Pure functions (tests/js/gaps.test.mjs).

/** The median step between consecutive times (0 with fewer than two). */
function medianStep(times) {
  const steps = [];
  for (let i = 1; i < times.length; i++) steps.push(times[i] - times[i - 1]);
  if (!steps.length) return 0;
  steps.sort((a, b) => a - b);
  return steps[Math.floor(steps.length / 2)];
}

/**
 * The longest step between two points that is not a hole, s: twice the decimated
 * telemetry's period (once the decimated stream is down there is a point at least that
 * often), twice the plot's bucket (`every_s`, a point per bucket at most), and three times
 * the points' usual step (an idle rover at a high clock speed records sparsely).
 * @param {number[]} times the points' t_s, ascending
 * @param {{decimate_s?: number, every_s?: number}} options
 */
export function gapAfterS(times, { decimate_s = 60, every_s = 0 } = {}) {
  return Math.max(2 * decimate_s, 2 * every_s, 3 * medianStep(times));
}

/**
 * Where to break the line: the indices i (1 ≤ i < times.length) such that the points i - 1
 * and i are more than `gapS` apart, or a reported gap ({first_t_s, last_t_s}: products the
 * store dropped) lies between them (or touches one of them).
 * @param {number[]} times ascending t_s
 * @param {number} gapS
 * @param {Array<{first_t_s: number, last_t_s: number}>} [dropped]
 * @returns {number[]}
 */
export function breaksBefore(times, gapS, dropped = []) {
  const out = [];
  for (let i = 1; i < times.length; i++) {
    const a = times[i - 1], b = times[i];
    const hole = b - a > gapS || dropped.some((g) => g.last_t_s >= a && g.first_t_s <= b);
    if (hole) out.push(i);
  }
  return out;
}

/**
 * `rows` (each with its `t_s`, ascending) with a `null` between the two rows of every hole
 * (breaksBefore): a plot draws no line across a null.
 * @template T
 * @param {T[]} rows
 * @param {number} gapS
 * @param {Array<{first_t_s: number, last_t_s: number}>} [dropped]
 * @returns {(T|null)[]}
 */
export function withBreaks(rows, gapS, dropped = []) {
  const breaks = new Set(breaksBefore(rows.map((r) => r.t_s), gapS, dropped));
  const out = [];
  rows.forEach((row, i) => {
    if (breaks.has(i)) out.push(null);
    out.push(row);
  });
  return out;
}
