// Signing in: who is at this console, and what their role lets them do. The token is kept
// in this browser tab's sessionStorage (and held by the API client, which sends it with
// every call), and in an HttpOnly cookie the server sets at sign-in so that the telemetry
// WebSocket and the 3D view can read on a server that needs a token for it.
import { api, detailText, heldToken, holdToken, onTokenRefused } from "./lib/api.js";
import { bus } from "./lib/bus.js";
import { $ } from "./lib/dom.js";
import { cookieOnly, greyControls } from "./lib/roles.js";

const KEPT = "roverops-token";
const SIGNED_OUT = "roverops-signed-out";
let me = null; // GET /api/me's body, or null when this tab may not read


// The greyed-out controls, the header's name, and "me" for the panels.
function applyRole() {
  greyControls(document, me, heldToken());
  const onlyCookie = cookieOnly(me, heldToken());
  const signedIn = Boolean(me && me.role) && !onlyCookie;
  $("who").textContent = signedIn ? `${me.name} · ${me.role}`
    : onlyCookie ? `${me.name} · reading (sign in to act)`
    : me ? "reading only" : "sign in to view";
  $("who").title = signedIn || onlyCookie ? $("who").textContent
    : me ? "not signed in: this server lets anyone read; sign in to act" : "this server needs a token to read";
  $("who").dataset.role = signedIn ? me.role : "";
  $("sign-out").hidden = !(me && me.role);
  $("sign-in").hidden = signedIn;
  $("token").hidden = signedIn;
  bus.emit("me", me);
}

// Asked with a candidate token ("" asks as nobody, the cookie aside).
const whoAmI = (token) => api("/api/me", { token });

// The held token counts only while /api/me names a role with it.
function becomes(body, token) {
  me = body;
  holdToken(me && me.role ? token : "");
}

// The API refused this tab's token (revoked or expired since sign-in): every call with it
// would be refused, reads too, so the tab forgets it and says so (a refused action says it
// again in its own words), and reads on as whoever it is without it.
onTokenRefused(async (detail) => {
  sessionStorage.removeItem(KEPT);
  sessionStorage.setItem(SIGNED_OUT, detail); // a reload right after still says why (once)
  me = null;
  applyRole(); // at once: no control acts with the forgotten token meanwhile
  $("sequence-status").textContent = `Signed out: ${detail}`;
  const r = await whoAmI("");
  becomes(r.ok ? r.body : null, "");
  applyRole();
});

// A refused sign-in is said at the form, where the operator is looking (and in the status
// line, the console's record of the last thing done); typing again puts it away.
function signInError(text) {
  $("sign-in-error").textContent = text;
  $("sign-in-error").hidden = !text;
  $("token").setAttribute("aria-invalid", String(Boolean(text)));
}

async function signIn() {
  const t = $("token").value.trim();
  const status = $("sequence-status");
  if (!t) { signInError("Paste your API token, then Sign in."); return; }
  // The token goes in the body (any character a token may hold; a header takes Latin-1
  // only), is checked, and sets the reading cookie; 403 says why it is refused.
  const r = await api("/api/session", {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ token: t }),
  });
  if (!r.ok) {
    status.textContent = `Not signed in: ${detailText(r)}`;
    signInError(status.textContent);
    return;
  }
  signInError("");
  sessionStorage.setItem(KEPT, t);
  $("token").value = "";
  becomes(r.body, t);
  status.textContent = `Signed in as ${r.body.name} (${r.body.role})`;
  applyRole();
  bus.emit("may-read");
}

async function signOut() {
  sessionStorage.removeItem(KEPT);
  holdToken("");
  await api("/api/session", { method: "DELETE" });
  const r = await whoAmI("");
  becomes(r.ok ? r.body : null, "");
  $("sequence-status").textContent = "Signed out";
  applyRole();
}

/** Who this tab is at page load (its kept token, if the API still takes it). */
export async function signInAtLoad() {
  $("sign-in").addEventListener("click", signIn);
  $("token").addEventListener("keydown", (e) => { if (e.key === "Enter") signIn(); });
  $("token").addEventListener("input", () => signInError(""));
  $("sign-out").addEventListener("click", signOut);
  const kept = sessionStorage.getItem(KEPT) || "";
  const signedOut = sessionStorage.getItem(SIGNED_OUT);
  sessionStorage.removeItem(SIGNED_OUT);
  if (signedOut) $("sequence-status").textContent = `Signed out: ${signedOut}`;
  let r = await whoAmI(kept);
  let token = kept;
  if (!r.ok && kept) { // a token revoked or expired since this tab signed in
    sessionStorage.removeItem(KEPT);
    $("sequence-status").textContent = `Signed out: ${detailText(r)}`;
    token = "";
    r = await whoAmI("");
  }
  becomes(r.ok ? r.body : null, token);
  applyRole();
  if (me) bus.emit("may-read");
}

// New controls drawn by a panel (its data-role buttons) are greyed out as the role says.
bus.on("controls", (root) => greyControls(root, me, heldToken()));
