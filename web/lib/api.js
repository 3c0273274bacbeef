// The console's one HTTP client. Every call carries this tab's signed-in token (GETs also
// have the sign-in cookie, but a cookie another tab cleared or replaced must not change
// what this tab reads, and a POST needs the token). Every answer has one shape,
// {ok, status, body}: a request that could not be sent (no network; a header the browser
// refuses) answers status 0 with the browser's reason as its detail, so the caller says it
// like any refusal.

let held = ""; // the token this tab signed in with ("" when none)
let refused = null; // called when the API refuses the held token

/** Keep (or with "" forget) the token every call sends. */
export function holdToken(token) { held = token || ""; }

/** The token every call sends ("" when this tab is not signed in). */
export function heldToken() { return held; }

/** `fn(detail)` runs when the API answers 403 "wrong token" to the held token (revoked or
 * expired since sign-in); the token is forgotten first. */
export function onTokenRefused(fn) { refused = fn; }

/**
 * @param {string} path
 * @param {RequestInit & {token?: string}} [options] token: present this token instead of
 *   the held one (a sign-in's check of a candidate; "" asks as nobody)
 * @returns {Promise<{ok: boolean, status: number, body: any}>}
 */
export async function api(path, options = {}) {
  const { token = held, headers = {}, ...rest } = options;
  const auth = token ? { Authorization: `Bearer ${token}` } : {};
  let response;
  try {
    response = await fetch(path, { ...rest, headers: { ...auth, ...headers } });
  } catch (e) {
    return { ok: false, status: 0, body: { detail: `not sent: ${e.message}` } };
  }
  let body = null;
  try { body = await response.json(); } catch (_) { body = null; }
  const wrong = body && typeof body.detail === "string" && body.detail.startsWith("wrong token");
  if (response.status === 403 && wrong && token && token === held) {
    held = "";
    if (refused) await refused(body.detail);
  }
  return { ok: response.ok, status: response.status, body };
}

/** What the API said, as one line: its sentence (401 "token required ...", 403 "wrong
 * token: ..." or "... needs the operator role"), the messages of a 422's list, or the
 * status. */
export function detailText(r) {
  const detail = r.body && r.body.detail;
  if (typeof detail === "string") return detail;
  if (Array.isArray(detail)) return detail.map((e) => (e && e.msg) || JSON.stringify(e)).join("; ");
  return `HTTP ${r.status}`;
}

/** The body of a successful GET; otherwise throws an Error whose message is detailText. */
export async function getJson(path) {
  const r = await api(path);
  if (!r.ok) throw new Error(detailText(r));
  return r.body;
}

/** Whether this server lets anyone read: /api/me asked with neither token nor cookie. */
export async function readsAnonymously() {
  try {
    return (await fetch("/api/me", { credentials: "omit" })).ok;
  } catch (_) { return false; }
}
