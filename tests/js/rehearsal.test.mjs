// A rehearsal's figures as the console writes them (web/lib/rehearsal.js): the request
// checked before it is sent, the progress words, the risk table's cells and the report's rows.
import assert from "node:assert/strict";
import { test } from "node:test";

import { SOL_S } from "../../web/lib/marstime.js";

import {
  aqfText as aqfTextNb, byName as byNameNb, durationText, ellipseText, finished, ordinal, parseRequest, placeText as placeTextNb,
  predictedBand, progress, rangeText, reportRows as reportRowsNb, requestBody, timelineBands, utcText, whenText,
  pct as pctNb,
} from "../../web/lib/rehearsal.js";

// figures and units are joined by no-break spaces; the tests read them as spaces
const plain = (s) => s.replaceAll("\u00a0", " ");
const pct = (p) => plain(pctNb(p));
const byName = (p) => plain(byNameNb(p));
const aqfText = (p) => plain(aqfTextNb(p));
const reportRows = (lines) => reportRowsNb(lines).map((r) => ({ ...r, place: plain(r.place) }));
const placeText = (f) => plain(placeTextNb(f));

test("runs and seed: defaults, bounds, and the seed kept exact up to 2^63 - 1", () => {
  assert.deepEqual(parseRequest("", ""), { runs: 100, seed: "0" });
  assert.deepEqual(parseRequest(" 8 ", "42"), { runs: 8, seed: "42" });
  assert.deepEqual(parseRequest("1000", "9223372036854775807"), { runs: 1000, seed: "9223372036854775807" });
  for (const runs of ["0", "1001", "2.5", "-3", "ten", "1e2"]) {
    assert.match(parseRequest(runs, "0").error, /^runs must be a whole number from 1 to 1000/, runs);
  }
  for (const seed of ["-1", "9223372036854775808", "1.5", "x"]) {
    assert.match(parseRequest("8", seed).error, /^seed must be a whole number from 0 to 2\^63 - 1/, seed);
  }
});

test("the request body is JSON, the seed's digits unrounded", () => {
  const body = requestBody({ text: 'SEQUENCE a\nDRIVE_STRAIGHT distance_m=2 "x"\n' }, 8, "9223372036854775807");
  assert.match(body, /"seed": 9223372036854775807}$/);
  const parsed = JSON.parse(body); // a double, but it parses: the text is what the server reads
  assert.equal(parsed.sequence_text, 'SEQUENCE a\nDRIVE_STRAIGHT distance_m=2 "x"\n');
  assert.equal(parsed.runs, 8);
  assert.deepEqual(JSON.parse(requestBody({ id: 7 }, 3, "0")), { sequence_id: 7, runs: 3, seed: 0 });
});

test("durations and progress: done of total, the ETA while running, the end state after", () => {
  assert.equal(durationText(44.6), "45 s");
  assert.equal(durationText(185), "3 min 05 s");
  assert.equal(durationText(3720), "1 h 02 min");
  assert.equal(durationText(null), "—");
  assert.deepEqual(progress({ state: "running", runs: 200, done: 50, eta_s: 90 }), { fraction: 0.25, words: "50 / 200 runs · ETA 1 min 30 s" });
  assert.equal(progress({ state: "running", runs: 8, done: 0, eta_s: null }).words, "0 / 8 runs · ETA once the first runs are in");
  assert.deepEqual(progress({ state: "done", runs: 8, done: 8, eta_s: 0 }), { fraction: 1, words: "8 / 8 runs · done" });
  assert.equal(progress({ state: "failed", runs: 8, done: 3, error: "worker died" }).words, "3 / 8 runs · failed: worker died");
  assert.equal(progress({ state: "cancelled", runs: 8, done: 3 }).fraction, 3 / 8);
  assert.ok(finished("done") && finished("cancelled") && finished("failed"));
  assert.ok(!finished("running") && !finished("queued"));
});

test("probabilities: rounded per cent, a rare event never reads as 0 %", () => {
  assert.equal(pct(0), "0 %");
  assert.equal(pct(0.004), "<1 %");
  assert.equal(pct(0.06), "6 %");
  assert.equal(pct(0.999), ">99 %");
  assert.equal(pct(1), "100 %");
  assert.equal(pct(null), "—");
  assert.equal(byName({ slip: 0.02, tilt: 0.03, rock: 0 }), "tilt 3 %, slip 2 %");
  assert.equal(byName({}), "none");
  assert.equal(aqfText({ Coarse: 0.1, Fine: 0.9 }), "Fine 90 %, Coarse 10 %");
});

test("an ellipse's semi-axes and its axis bearing, in [0, 180)°", () => {
  assert.equal(ellipseText({ a_m: 0.4213, b_m: 0.18, angle_deg: 35.2 }), "0.42 × 0.18 m, 35°");
  assert.equal(ellipseText({ a_m: 1, b_m: 0.5, angle_deg: -30 }), "1.00 × 0.50 m, 150°");
  assert.equal(ellipseText({ a_m: 1, b_m: 0.5, angle_deg: 190 }), "1.00 × 0.50 m, 10°");
  assert.equal(ellipseText(null), "—");
  assert.equal(rangeText({ p5: 8, p50: 12, p95: 20 }, (v) => `${v} s`), "12 s (8 s–20 s)");
  assert.equal(rangeText(null, String), "—");
});

test("ordinals", () => {
  assert.deepEqual([1, 2, 3, 4, 11, 12, 13, 21, 22, 99, 37.5].map(ordinal),
    ["1st", "2nd", "3rd", "4th", "11th", "12th", "13th", "21st", "22nd", "99th", "38th"]);
});

test("the report's rows: one per figure, flagged outside 95 %, each place in words", () => {
  const rows = reportRows([{ line: 2, command: "DRIVE_STRAIGHT distance_m=2", figures: [
    { name: "end_t_s", executed: 1234.5, percentile: 99.2, outside_95: true },
    { name: "end_est", executed: [1.99, 0.013], mahalanobis2: 1.2, percentile: 45.1, outside_95: false },
    { name: "status", executed: "completed", probability: 0.97, outside_95: false },
  ] }]);
  assert.equal(rows.length, 3);
  assert.deepEqual(rows.map((r) => r.outside), [true, false, false]);
  assert.deepEqual(rows.map((r) => r.words), ["end time", "end pose (estimate)", "status"]);
  assert.equal(rows[0].place, "99th percentile");
  assert.equal(rows[1].executed, "(1.99, 0.01) m");
  assert.equal(rows[0].executed, "1234.50 s"); // no moment to count sol and LMST from
  const ref = { t_s: 1234.5, sol: 7, lmst_h: 13.25 };
  assert.equal(reportRowsNb([{ line: 2, figures: [{ name: "end_t_s", executed: 1234.5 }] }], ref)[0].executed, "sol 7 13:15:00 LMST");
  assert.deepEqual(reportRowsNb([{ line: 2, figures: [
    { name: "imu_integration_s", executed: 66.75 }, { name: "heading_est_deg", executed: 359.84 },
    { name: "position_sigma_m", executed: 2 }, { name: "aqf", executed: "Fine", probability: 1 }] }]).map((r) => [r.words, r.executed]),
  [["IMU time", "66.75 s"], ["heading (estimate)", "359.84°"], ["position σ", "2 m"], ["AQF", "Fine"]]);
  assert.equal(rows[1].place, "45th percentile, d² 1.20");
  assert.equal(rows[2].place, "predicted 97 %");
  assert.equal(placeText({ name: "x", executed: null }), "—");
  assert.deepEqual(reportRows(null), []);
});

test("a line's predicted band: start p5 to end p95 outside, medians inside; none if it never ran", () => {
  const band = predictedBand({ start_t_s: { p5: 10, p50: 12, p95: 15 }, end_t_s: { p5: 40, p50: 50, p95: 70 } });
  assert.deepEqual(band, { outer: [10, 70], inner: [12, 50] });
  assert.equal(predictedBand({ start_t_s: null, end_t_s: null }), null);
});

test("a time as sol and LMST, counted from a known moment, across midnight", () => {
  const ref = { t_s: 1000, sol: 3, lmst_h: 23.5 };
  assert.equal(whenText(1000, ref), "sol 3 23:30:00 LMST");
  assert.equal(whenText(1000 + SOL_S / 24, ref), "sol 4 00:30:00 LMST"); // an hour of LMST later
  assert.equal(whenText(1000 - SOL_S, ref), "sol 2 23:30:00 LMST");
  assert.equal(whenText(null, ref), "—");
  assert.equal(whenText(5, null), "—");
});

test("the timeline's bands: as predicted until the sequence runs, then moved onto its start", () => {
  const line = (n, command, s, e) => ({ line: n, command, verdict: "ok",
    start_t_s: { p5: s - 1, p50: s, p95: s + 1 }, end_t_s: { p5: e - 2, p50: e, p95: e + 3 } });
  const risk = { lines: [line(2, "DRIVE_STRAIGHT  distance_m=2", 100, 160), line(3, "SUNCHECK_SUNGAZE", 160, 400),
    { line: 4, command: "X", verdict: "risk", start_t_s: null, end_t_s: null }] };
  const alone = timelineBands({ sequence_id: null }, risk, []);
  assert.equal(alone.shift_s, 0);
  assert.deepEqual(alone.bands.map((b) => b.outer), [[99, 163], [159, 403]]); // line 4 never ran
  const commands = [
    { sequence_id: 5, step_index: 0, command: "DRIVE_STRAIGHT distance_m=2", start: { t_s: 900 } },
    { sequence_id: 6, step_index: 0, command: "DRIVE_STRAIGHT distance_m=2", start: { t_s: 1500 } },
    { sequence_id: 6, step_index: 1, command: "SUNCHECK_SUNGAZE", start: { t_s: 1560 } },
  ];
  const byText = timelineBands({ sequence_id: null }, risk, commands); // the newest with that first line
  assert.equal(byText.sequence_id, 6);
  assert.equal(byText.shift_s, 1400);
  assert.deepEqual(byText.bands[0].inner, [1500, 1560]);
  const byId = timelineBands({ sequence_id: 5 }, risk, commands);
  assert.equal(byId.shift_s, 800);
  assert.deepEqual(timelineBands({ sequence_id: 9 }, risk, commands).shift_s, 0); // not run yet
});

test("a stored UTC time, to the second", () => {
  assert.equal(utcText("2026-12-05T04:58:37.174705+00:00"), "2026-12-05 04:58:37 UTC");
  assert.equal(utcText("2026-12-05T04:58:37Z"), "2026-12-05 04:58:37 UTC");
  assert.equal(utcText(null), "—");
  assert.equal(utcText("yesterday"), "yesterday");
});
