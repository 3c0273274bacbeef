// roverops console: the viser 3D view of the selected rover, embedded from the same origin
// (/viser/{rover}/, proxied by the server). The view keeps its own state on the server, so
// switching rovers or reloading the page only points the frame at another URL.
//
// A same-origin frame shares the page's main thread, and viser renders in software where
// there is no GPU (SwiftShader): loading and drawing it can hold the page's thread for
// seconds on a busy machine (issue 14, item 12: the readouts and the timeline waited on it).
// So the frame is loaded once the console has shown its first state, and only while it is
// in sight; scrolled out of sight it is paused (display: none stops its drawing; its
// WebSocket and scene stay, so it is current again when it comes back).
"use strict";

(() => {
  const byId = (id) => document.getElementById(id);
  const view = { url: null, ready: false, inSight: false };

  function apply() {
    const frame = byId("view3d");
    if (view.url && view.ready && view.inSight && frame.getAttribute("src") !== view.url) {
      frame.setAttribute("src", view.url);
    }
    frame.classList.toggle("paused", !view.inSight);
  }

  async function show(rover) {
    const frame = byId("view3d");
    const note = byId("view3d-status");
    const response = await fetch(`/api/rovers/${encodeURIComponent(rover)}/scene`);
    if (!response.ok) {
      let detail = `HTTP ${response.status}`;
      try { detail = (await response.json()).detail; } catch (_) { /* not JSON */ }
      frame.hidden = true;
      note.textContent = `3D view unavailable: ${detail}`;
      return;
    }
    const scene = await response.json();
    view.url = scene.url;
    frame.hidden = false;
    byId("view3d-open").href = scene.url;
    note.textContent = "";
    apply();
  }

  new IntersectionObserver((entries) => {
    view.inSight = entries[entries.length - 1].isIntersecting;
    apply();
  }).observe(byId("view3d-box"));

  roverops.on("state", () => {
    if (view.ready) return;
    view.ready = true;
    apply();
  });
  roverops.on("rover", (rover) => { if (rover) show(rover); });
  if (roverops.state.rover) show(roverops.state.rover);
})();
