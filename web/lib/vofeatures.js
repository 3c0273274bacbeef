// What a VO step saw, as marks to draw over its left image (images.js): Cheng, Maimone and
// Matthies 2005 Figs. 5-6 draw the features and the tracked ones with their motion.

/**
 * The marks to draw over the left image, in its pixels (a pixel's centre at u + 0.5):
 * a circle per feature, and per tracked feature a line (previous → new) and a dot, inlier
 * or outlier. Sizes scale with the image (2 px at 256 wide).
 * @param {{width_px: number, features: null | {features_uv_px: number[][],
 *   tracked_previous_uv_px: number[][], tracked_uv_px: number[][], inlier: boolean[]}}} image
 * @returns {{kind: string, cls: string, attrs: Record<string, number>}[]}
 */
export function overlayMarks(image) {
  const f = image.features;
  if (!f) return [];
  const r = Math.max(1, image.width_px / 128);
  const c = (x) => x + 0.5;
  const marks = f.features_uv_px.map(([u, v]) => ({
    kind: "circle", cls: "feature", attrs: { cx: c(u), cy: c(v), r: 1.6 * r, "stroke-width": r / 2 },
  }));
  f.tracked_uv_px.forEach(([u, v], i) => {
    const [u0, v0] = f.tracked_previous_uv_px[i];
    const cls = f.inlier[i] ? "inlier" : "outlier";
    marks.push({ kind: "line", cls: `track ${cls}`, attrs: { x1: c(u0), y1: c(v0), x2: c(u), y2: c(v), "stroke-width": r / 2 } });
    marks.push({ kind: "circle", cls: `tracked ${cls}`, attrs: { cx: c(u), cy: c(v), r } });
  });
  return marks;
}
