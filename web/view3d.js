// roverops console: the viser 3D view of the selected rover, embedded from the same origin
// (/viser/{rover}/, proxied by the server). The view keeps its own state on the server, so
// switching rovers or reloading the page only points the frame at another URL.
"use strict";

(() => {
  const byId = (id) => document.getElementById(id);

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
    if (frame.getAttribute("src") !== scene.url) frame.setAttribute("src", scene.url);
    frame.hidden = false;
    byId("view3d-open").href = scene.url;
    note.textContent = "";
  }

  // console.js fills the rover picker once it has asked the server for the rovers.
  function whenRoverKnown(then) {
    if (byId("rover").value) { then(); return; }
    const watcher = new MutationObserver(() => {
      if (!byId("rover").value) return;
      watcher.disconnect();
      then();
    });
    watcher.observe(byId("rover"), { childList: true });
  }

  whenRoverKnown(() => {
    show(byId("rover").value);
    byId("rover").addEventListener("change", () => show(byId("rover").value));
  });
})();
