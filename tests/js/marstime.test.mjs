// The console's Mars-time formatting against the Python Mars clock (sim/world/marsclock.py):
// lmst_reference.json holds its LMST at moments of four sols (`roverops web-types` writes it,
// tests/cli/test_web_types.py fails when it differs from what the clock computes).
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { test } from "node:test";

import { LMST_HOUR_S, SOL_S, lmstAt, lmstText } from "../../web/lib/marstime.js";

const reference = JSON.parse(readFileSync(new URL("./lmst_reference.json", import.meta.url)));
const moments = reference.sols.flatMap((s) => s.moments.map((m) => ({ ...m, sol: s })));

test("the reference covers four sols, past midnight too", () => {
  assert.equal(reference.sols.length, 4);
  assert.ok(moments.some((m) => m.sols_after === 1));
});

test("LMST hours read as the Python clock's reading, hh:mm:ss truncated", () => {
  for (const m of moments) assert.equal(lmstText(m.lmst_h), m.text, `t_s ${m.t_s}`);
});

test("LMST without seconds is the reading's hours and minutes", () => {
  for (const m of moments) assert.equal(lmstText(m.lmst_h, { seconds: false }), m.text.slice(0, 5));
});

test("LMST counted on from the sol's start equals the Python clock's, past midnight too", () => {
  // a millisecond of LMST: the clock is linear in TT, so only rounding separates them
  const tolerance_h = 1e-3 / 3600;
  for (const m of moments) {
    const expected_h = m.lmst_h + 24 * m.sols_after;
    const got_h = lmstAt(m.t_s, m.sol.start);
    assert.ok(Math.abs(got_h - expected_h) < tolerance_h, `t_s ${m.t_s}: ${got_h} vs ${expected_h}`);
    assert.equal(lmstText(got_h), m.text);
  }
});

test("a sol is 24 LMST hours of SOL_S seconds", () => {
  const start = reference.sols[0].start;
  assert.ok(Math.abs(lmstAt(start.t_s + SOL_S, start) - start.lmst_h - 24) < 1e-12);
  assert.equal(LMST_HOUR_S * 24, SOL_S);
});

test("a reading wraps into one day, before midnight and after", () => {
  assert.equal(lmstText(24 + 1 / 60), "00:01:00");
  assert.equal(lmstText(-1 / 3600), "23:59:59");
});
