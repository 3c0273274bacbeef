// A drive line given the advisor's pointing (web/lib/pointing.js).
import assert from "node:assert/strict";
import { test } from "node:test";

import { lineAt, textWithPointing, withPointing } from "../../web/lib/pointing.js";

test("the pointing is appended, replacing any the line had, before its comment", () => {
  const args = "vo_az_deg=90 vo_el_deg=-35";
  assert.equal(withPointing("DRIVE_STRAIGHT distance_m=3 vo=on", args),
    "DRIVE_STRAIGHT distance_m=3 vo=on vo_az_deg=90 vo_el_deg=-35");
  assert.equal(withPointing("DRIVE_STRAIGHT distance_m=3 vo=on vo_az_deg=0 vo_el_deg=-45", args),
    "DRIVE_STRAIGHT distance_m=3 vo=on vo_az_deg=90 vo_el_deg=-35");
  assert.equal(withPointing("  DRIVE_ARC radius_m=4 angle_deg=20 vo=on  # round the rock", args),
    "  DRIVE_ARC radius_m=4 angle_deg=20 vo=on vo_az_deg=90 vo_el_deg=-35    # round the rock");
});

test("the caret's line, and only that line of a text changes", () => {
  const text = "SEQUENCE s\r\nWAIT duration_s=5\nDRIVE_STRAIGHT distance_m=3 vo=on\n";
  assert.equal(lineAt(text, 0), 1);
  assert.equal(lineAt(text, text.indexOf("DRIVE")), 3);
  assert.equal(textWithPointing(text, 3, "vo_az_deg=-90 vo_el_deg=-35"),
    "SEQUENCE s\r\nWAIT duration_s=5\nDRIVE_STRAIGHT distance_m=3 vo=on vo_az_deg=-90 vo_el_deg=-35\n");
  assert.equal(textWithPointing(text, 9, "x"), text);
});
