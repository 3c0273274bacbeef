// The pair the rover sent, opened from its mark on the timeline (timeline/images.js, the
// bus's "image"): its left and right images as stored (PNG, GET .../images/{id}/left.png and
// right.png) and, over the left one, what the VO step saw as Cheng, Maimone and Matthies 2005
// draw it (Figs. 5-6): the features matched in this pair, and the previous pair's features
// tracked into it, each with its motion (a line from where it was to where it is), inliers
// green and outliers red; with the step's status and counts.
import { api, detailText, heldToken } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $ } from "./lib/dom.js";
import { overlayMarks } from "./lib/vofeatures.js";
import { imageWords } from "./timeline/images.js";

const SVG = "http://www.w3.org/2000/svg";

function drawOverlay(image) {
  const svg = $("image-overlay");
  svg.setAttribute("viewBox", `0 0 ${image.width_px} ${image.height_px}`);
  svg.replaceChildren(...overlayMarks(image).map((m) => {
    const node = document.createElementNS(SVG, m.kind);
    node.setAttribute("class", m.cls);
    for (const [k, v] of Object.entries(m.attrs)) node.setAttribute(k, String(v));
    if (m.cls === "feature") node.dataset.testid = "feature-marker";
    if (m.cls.startsWith("tracked")) {
      node.dataset.testid = "track-marker";
      node.dataset.inlier = m.cls.includes("inlier") ? "1" : "0";
    }
    return node;
  }));
}

const urls = []; // the object URLs of the images shown, revoked when others replace them

// The PNG as stored, with this tab's token (a browser keeps it: the server says immutable).
async function showPng(img, path) {
  const token = heldToken();
  const response = await fetch(path, { headers: token ? { Authorization: `Bearer ${token}` } : {} });
  if (!response.ok) throw new Error(`${path}: HTTP ${response.status}`);
  const url = URL.createObjectURL(await response.blob());
  urls.push(url);
  await new Promise((resolve, reject) => {
    img.onload = resolve;
    img.onerror = () => reject(new Error(`${path}: not an image`));
    img.src = url;
  });
}

function summary(image) {
  const p = image.p_mission_est.map((x) => x.toFixed(2)).join(", ");
  const parts = [`${image.width_px} × ${image.height_px}`, `mast az ${image.mast_az_deg.toFixed(1)}°, el ${image.mast_el_deg.toFixed(1)}°`,
    `estimated position (${p}) m, mission frame`];
  if (image.vo) {
    const vo = image.vo;
    parts.unshift(`${vo.n_features} features, ${vo.n_tracked} tracked, ${vo.n_inliers} inliers, ${vo.n_tracked - vo.n_inliers} outliers`);
    if (vo.step > 0 && vo.status !== "converged") parts.push(vo.reason);
  }
  if (image.received_t_s !== null && image.received_t_s !== undefined) parts.push("came down across light time");
  return parts.join(" · ");
}

async function open({ rover, id }) {
  const dialog = $("image-dialog");
  const base = `/api/rovers/${encodeURIComponent(rover)}/images/${id}`;
  dialog.dataset.imageId = String(id);
  dialog.dataset.loaded = "";
  $("image-title").textContent = "Loading…";
  $("image-summary").textContent = "";
  $("image-status").textContent = "";
  $("image-overlay").replaceChildren();
  if (!dialog.open) dialog.showModal();
  const r = await api(base);
  if (String(id) !== dialog.dataset.imageId) return; // another opened meanwhile
  if (!r.ok) { $("image-title").textContent = `Image ${id}: ${detailText(r)}`; return; }
  const image = r.body;
  $("image-title").textContent = `${imageWords(image)} (#${image.id})`;
  const status = $("image-status");
  status.textContent = image.vo ? image.vo.status : "";
  status.className = `image-status ${image.vo && image.vo.step > 0 ? (image.vo.status === "converged" ? "good" : "bad") : ""}`;
  $("image-summary").textContent = summary(image);
  drawOverlay(image);
  while (urls.length) URL.revokeObjectURL(urls.pop());
  try {
    await Promise.all([showPng($("image-left"), `${base}/left.png`), showPng($("image-right"), `${base}/right.png`)]);
    if (String(id) === dialog.dataset.imageId) dialog.dataset.loaded = "1";
  } catch (err) {
    $("image-summary").textContent = `${summary(image)} · could not load the images: ${err.message}`;
  }
}

function start() {
  bus.on("image", (which) => { open(which).catch((err) => { $("image-title").textContent = err.message; }); });
  $("image-close").addEventListener("click", () => $("image-dialog").close());
}

start();
