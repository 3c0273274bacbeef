// The marks drawn over a VO pair's left image (web/lib/vofeatures.js): one circle per
// feature, and per tracked feature its motion line and dot, coloured by inlier or outlier.
import assert from "node:assert/strict";
import { test } from "node:test";

import { overlayMarks } from "../../web/lib/vofeatures.js";

const image = {
  width_px: 256,
  features: {
    features_uv_px: [[10, 20], [30, 40], [50, 60]],
    tracked_previous_uv_px: [[1, 2], [3, 4]],
    tracked_uv_px: [[5, 6], [7, 8]],
    inlier: [true, false],
  },
};

test("a feature is a circle at its pixel's centre", () => {
  const features = overlayMarks(image).filter((m) => m.cls === "feature");
  assert.equal(features.length, 3);
  assert.deepEqual([features[1].attrs.cx, features[1].attrs.cy], [30.5, 40.5]);
});

test("a tracked feature is a line from where it was to where it is, and a dot there", () => {
  const marks = overlayMarks(image);
  const lines = marks.filter((m) => m.kind === "line");
  const dots = marks.filter((m) => m.cls.startsWith("tracked"));
  assert.deepEqual(lines.map((l) => [l.attrs.x1, l.attrs.y1, l.attrs.x2, l.attrs.y2]), [[1.5, 2.5, 5.5, 6.5], [3.5, 4.5, 7.5, 8.5]]);
  assert.deepEqual(dots.map((d) => d.cls), ["tracked inlier", "tracked outlier"]);
  assert.deepEqual(lines.map((l) => l.cls), ["track inlier", "track outlier"]);
});

test("a pair without features (a Navcam pair) has no marks; sizes grow with the image", () => {
  assert.deepEqual(overlayMarks({ width_px: 256, features: null }), []);
  const big = overlayMarks({ ...image, width_px: 1024 })[0].attrs.r;
  assert.equal(big, 4 * overlayMarks(image)[0].attrs.r);
});
