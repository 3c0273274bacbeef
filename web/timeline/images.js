// The sol timeline's Images lane: a mark for each image the rover sent that has reached the
// ground (GET /api/rovers/{rover}/images over the sol, read with the sol by panel.js): the
// VO pairs a vo_keep_images=on drive kept (green converged, red failed, grey a drive's
// first pair) and the NAVCAM_STEREO pairs (blue). A click opens the pair (images.js, through
// the bus's "image"). Images come down with their frames, so the lane is read again when
// the sol is (reconcile), and a moment after each command the rover reports.
import { api } from "../lib/api.js";
import { bus } from "../lib/bus.js";
import { $, el } from "../lib/dom.js";
import { lmstAt, lmstText } from "../lib/marstime.js";
import { solSpan } from "./comm.js";
import { view } from "./view.js";

const AFTER_COMMAND_MS = 1000; // a command's images are stored with its last frames

/** The sol's images: GET .../images from midnight to midnight of the sol. */
export function imagesPath(rover, timeline) {
  const [from, to] = solSpan(timeline);
  const query = new URLSearchParams({ from: from.toFixed(3), to: to.toFixed(3), limit: "1000" });
  return `/api/rovers/${encodeURIComponent(rover)}/images?${query}`;
}

/** The sol's images, or none from a server without them. */
export async function fetchImages(rover, timeline) {
  const r = await api(imagesPath(rover, timeline));
  return r.ok ? r.body.images : [];
}

/** A mark's words: what the image is, and a VO pair's outcome. */
export function imageWords(image) {
  if (image.kind !== "vo_pair" || !image.vo) {
    return `Navcam stereo pair, az ${image.mast_az_deg.toFixed(1)}°, el ${image.mast_el_deg.toFixed(1)}°`;
  }
  const vo = image.vo;
  if (vo.step === 0) return `VO pair, the drive's first (${vo.n_features} features)`;
  return `VO pair, step ${vo.step}/${vo.steps}: ${vo.status} (${vo.n_inliers} of ${vo.n_tracked} tracked are inliers)`;
}

function statusOf(image) {
  if (image.kind !== "vo_pair" || !image.vo) return "navcam";
  if (image.vo.step === 0) return "first";
  return image.vo.status === "converged" ? "converged" : "failed";
}

function imageMark(image, timeline) {
  const at = lmstAt(image.t_s, timeline.start);
  const status = statusOf(image);
  const mark = el("button", {
    type: "button",
    className: `tl-image tl-at image-${status}`,
    title: `${lmstText(at % 24)} LMST\n${imageWords(image)}\nclick to open the pair`,
    dataset: { testid: "timeline-image", imageId: String(image.id), kind: image.kind, status },
  });
  mark.style.setProperty("--s", String(at));
  mark.setAttribute("aria-label", imageWords(image));
  mark.addEventListener("click", () => bus.emit("image", { rover: view.rover, id: image.id }));
  return mark;
}

let pending = null; // the read after a command, once

export const imageLane = {
  id: "lane-images",
  draw(timeline) { $(this.id).replaceChildren(...(timeline.images || []).map((i) => imageMark(i, timeline))); },
  reconcile(timeline) { this.draw(timeline); },
  command() {
    if (pending) return;
    pending = setTimeout(async () => {
      pending = null;
      const timeline = view.timeline;
      if (!timeline || !view.rover) return;
      const images = await fetchImages(view.rover, timeline);
      if (timeline !== view.timeline) return; // another sol meanwhile
      timeline.images = images;
      this.draw(timeline);
    }, AFTER_COMMAND_MS);
  },
};
