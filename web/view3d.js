// roverops console: the viser 3D view of the selected rover (/viser/{rover}/, proxied by
// the server). The view keeps its own state on the server, so switching rovers or reloading
// the page only points the frame at another URL.
//
// Without a GPU, browsers draw WebGL in software (SwiftShader, llvmpipe), and a frame of the
// page's own site shares the page's process and main thread: loading and drawing the view
// held the console's thread for seconds (issue 21: a sign-in took 9-110 s with the view
// shown, under a second without it). So:
// - On a loopback address the frame is loaded from the other loopback name (localhost for
//   127.0.0.1, and back), the same server: another site, which a browser with site
//   isolation (Chromium, Firefox) renders in a process of its own, off the console's
//   thread. Only where reading needs no token: the sign-in cookie is the console host's own.
// - Where the frame would share the page's thread (one name, say behind a proxy) and WebGL
//   is software, the view starts hidden, and a note says why.
// - Each browser can hide the view (its toggle; the choice is kept in localStorage). Hidden,
//   the frame is unloaded (about:blank: its drawing, its scene and its WebSocket end); shown,
//   it loads again.
// - It is loaded once the console has shown its first state, and only while in sight;
//   scrolled out of sight it is paused (display: none stops its drawing; its WebSocket and
//   scene stay, so it is current again when it comes back).
import { api, detailText, readsAnonymously } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $ } from "./lib/dom.js";

const KEPT = "roverops-view3d"; // "shown" or "hidden", this browser's choice
const LOOPBACK_TWIN = { "127.0.0.1": "localhost", localhost: "127.0.0.1", "[::1]": "localhost" };
const SOFTWARE_GL = /swiftshader|llvmpipe|softpipe|software/i;
const view = { path: null, src: null, ready: false, inSight: false, shown: true, origin: null };

// The origin the frame is loaded from: the loopback twin of this page's host when anyone
// may read (asked without the cookie), else this page's own ("").
async function frameOrigin() {
  const twin = LOOPBACK_TWIN[location.hostname];
  if (!twin) return "";
  if (!(await readsAnonymously())) return "";
  return `${location.protocol}//${twin}${location.port ? `:${location.port}` : ""}`;
}

// The renderer's name when this browser draws WebGL in software (or has none), else null.
function softwareWebGL() {
  try {
    const gl = document.createElement("canvas").getContext("webgl");
    if (!gl) return "no WebGL";
    const info = gl.getExtension("WEBGL_debug_renderer_info");
    const name = String(gl.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
    const lose = gl.getExtension("WEBGL_lose_context");
    if (lose) lose.loseContext();
    return SOFTWARE_GL.test(name) ? name : null;
  } catch (_) { return null; }
}

function apply() {
  const frame = $("view3d");
  const toggle = $("view3d-toggle");
  toggle.setAttribute("aria-expanded", String(view.shown));
  toggle.textContent = view.shown ? "Hide" : "Show";
  toggle.title = view.shown ? "hide the 3D view: it stops drawing and is unloaded"
    : "show the 3D view (this browser remembers the choice)";
  $("view3d-box").hidden = !view.shown;
  if (!view.shown) {
    if (frame.getAttribute("src") !== "about:blank") frame.setAttribute("src", "about:blank");
    return;
  }
  if (view.src && view.ready && view.inSight && frame.getAttribute("src") !== view.src) {
    frame.setAttribute("src", view.src);
  }
  frame.classList.toggle("paused", !view.inSight);
}

// Whether to show the view before this browser has chosen, and the note if not.
function firstChoice() {
  const kept = localStorage.getItem(KEPT);
  if (kept === "shown" || kept === "hidden") return { shown: kept === "shown", note: "" };
  if (view.origin) return { shown: true, note: "" }; // in its own process: harmless
  const software = softwareWebGL();
  if (!software) return { shown: true, note: "" };
  return {
    shown: false,
    note: `3D view hidden: this browser draws WebGL in software (${software}), and here the`
      + " view would share the console's thread and slow every readout. Show it to load it anyway.",
  };
}

async function show(rover) {
  const frame = $("view3d");
  const note = $("view3d-status");
  if (view.origin === null) {
    view.origin = await frameOrigin();
    const first = firstChoice();
    view.shown = first.shown;
    note.textContent = first.note;
  }
  const r = await api(`/api/rovers/${encodeURIComponent(rover)}/scene`);
  if (!r.ok) {
    frame.hidden = true;
    $("view3d-toggle").hidden = true; // nothing to show or hide
    note.textContent = `3D view unavailable: ${detailText(r)}`;
    return;
  }
  const scene = r.body;
  view.path = scene.url;
  view.src = view.origin + scene.url;
  frame.hidden = false;
  $("view3d-toggle").hidden = false;
  $("view3d-open").href = scene.url;
  apply();
}

$("view3d-toggle").addEventListener("click", () => {
  view.shown = !view.shown;
  localStorage.setItem(KEPT, view.shown ? "shown" : "hidden");
  $("view3d-status").textContent = "";
  apply();
});

new IntersectionObserver((entries) => {
  view.inSight = entries[entries.length - 1].isIntersecting;
  apply();
}).observe($("view3d-box"));

bus.on("state", () => {
  if (view.ready) return;
  view.ready = true;
  apply();
});
bus.on("rover", (rover) => { if (rover) show(rover); });
