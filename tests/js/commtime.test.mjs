// The link's words (web/lib/commtime.js) and the plots' holes (web/lib/gaps.js).
import assert from "node:assert/strict";
import { test } from "node:test";

import {
  agoText, arrivalText, clockText, dataAgeText, durationText, fillText, hmText, mbitText, momentText,
  staleAfterS, untilText,
} from "../../web/lib/commtime.js";
import { breaksBefore, gapAfterS, withBreaks } from "../../web/lib/gaps.js";
import { LMST_HOUR_S } from "../../web/lib/marstime.js";

test("the light time reads as min:s, and h:mm:ss from an hour", () => {
  assert.equal(clockText(1018.46), "16:58");
  assert.equal(clockText(185), "3:05");
  assert.equal(clockText(59.6), "1:00");
  assert.equal(clockText(3723), "1:02:03");
  assert.equal(clockText(-4), "0:00");
});

test("durations to the minute, hours with two-digit minutes", () => {
  assert.equal(durationText(59), "under a minute");
  assert.equal(durationText(60), "1 min");
  assert.equal(durationText(17 * 60 + 59), "17 min");
  assert.equal(durationText(3600 + 5 * 60), "1 h 05 min");
  assert.equal(durationText(26 * 3600), "26 h 00 min");
  assert.equal(agoText(30), "just now");
  assert.equal(agoText(9 * 60 + 10), "9 min ago");
});

test("a moment and the data's age say the sol, LMST to the minute, and how long ago", () => {
  const data = { sol: 412, lmst_h: 14 + 2 / 60 + 30 / 3600 };
  assert.equal(momentText(data), "sol 412 14:02 LMST");
  assert.equal(dataAgeText(data, 9 * 60), "data of sol 412 14:02 LMST, received 9 min ago");
  assert.equal(dataAgeText(data, null), "data of sol 412 14:02 LMST");
  assert.equal(arrivalText(data, 17 * 60 + 20), "data of sol 412 14:02 LMST, received 17 min later");
  assert.equal(arrivalText(data, 30 * 60 + 40), "data of sol 412 14:02 LMST, received 31 min later");
  // a window computed to open at 09:00 reads 09:00, a clock at 09:00:59 reads 09:00
  assert.equal(hmText(8.99999999627471), "09:00");
  assert.equal(hmText(9 + 59 / 3600), "09:00");
});

test("data is stale past the relay's delay, the light time and a pass", () => {
  assert.equal(staleAfterS({ relay_latency_s: 1800 }, 1000), 1800 + 1000 + 900);
  assert.equal(staleAfterS(null, 600), 600 + 900);
});

test("a window is ahead, open or over", () => {
  const w = { start_t_s: 1000, end_t_s: 1000 + 11 * 60 };
  assert.equal(untilText(1000 - 26 * 60, w), "in 26 min");
  assert.equal(untilText(1000 - 2 * LMST_HOUR_S, w), "in 2 h 03 min");
  assert.equal(untilText(1000 + 60, w), "open, 10 min left");
  assert.equal(untilText(w.end_t_s + 180, w), "ended 3 min ago");
});

test("volumes and the store's fill keep a few digits", () => {
  assert.equal(mbitText(87.6125), "87.6 Mbit");
  assert.equal(mbitText(7.2), "7.20 Mbit");
  assert.equal(mbitText(0.0125), "12.5 kbit");
  assert.equal(mbitText(0), "0 bit");
  assert.equal(mbitText(null), "0 bit");
  assert.equal(fillText(37.4), "37 %");
  assert.equal(fillText(2.46), "2.5 %");
  assert.equal(fillText(0.00428125), "0.0043 %");
  assert.equal(fillText(0), "0 %");
});

test("a hole is a step over twice the decimated period, twice the bucket, thrice the usual", () => {
  const every10 = Array.from({ length: 20 }, (_, i) => 10 * i);
  assert.equal(gapAfterS(every10, { decimate_s: 60 }), 120);
  assert.equal(gapAfterS(every10, { decimate_s: 60, every_s: 90 }), 180);
  const sparse = Array.from({ length: 20 }, (_, i) => 500 * i); // idle at 10,000x
  assert.equal(gapAfterS(sparse, { decimate_s: 60 }), 1500);
  assert.equal(gapAfterS([], {}), 120);
});

test("breaks go where points are far apart or a reported drop lies between them", () => {
  const times = [0, 10, 20, 500, 510, 520, 530];
  assert.deepEqual(breaksBefore(times, 120), [3]);
  assert.deepEqual(breaksBefore(times, 120, [{ first_t_s: 512, last_t_s: 518 }]), [3, 5]);
  assert.deepEqual(breaksBefore(times, 1000), []);
  const rows = times.map((t_s) => ({ t_s }));
  const broken = withBreaks(rows, 120);
  assert.equal(broken.length, rows.length + 1);
  assert.equal(broken[3], null);
  assert.deepEqual(broken.filter(Boolean), rows);
});
