// Roles at this console: what the signed-in user may do, and the controls that say so.

export const ROLES = ["viewer", "operator", "conductor", "admin"]; // each may do all before it

/** Whether `me` (GET /api/me's body, or null) may use a control needing `role`. A role above
 * viewer acts with the token this tab holds: a tab that reads with the browser's sign-in
 * cookie alone (another tab signed in) would be answered 401 "token required". */
export function mayAct(me, tokenHeld, role) {
  const mine = me && me.role ? ROLES.indexOf(me.role) : -1;
  if (ROLES.indexOf(role) > 0 && !tokenHeld) return false;
  return mine >= ROLES.indexOf(role);
}

/** Signed in elsewhere: this tab reads with the cookie but holds no token. */
export const cookieOnly = (me, tokenHeld) => Boolean(me && me.role) && !tokenHeld;

/** Controls under `root` carry data-role="operator" (the lowest role the server accepts for
 * them): those `me` may not use are disabled and say why. */
export function greyControls(root, me, tokenHeld) {
  for (const control of root.querySelectorAll("[data-role]")) {
    const needed = control.dataset.role;
    control.disabled = !mayAct(me, tokenHeld, needed);
    control.title = !control.disabled ? ""
      : cookieOnly(me, tokenHeld) ? `needs the ${needed} role: sign in in this tab (the token is kept per tab)`
      : `needs the ${needed} role: sign in with a ${needed}'s token`;
  }
}
