// Mars time at the console's edge: the server sends LMST in hours (sim/world/marsclock.py
// lmst_h_from_t_s, Allison and McEwen 2000) and TT seconds; this formats them.

/** A Mars mean solar day, s: LMST advances 24 h in it (Allison and McEwen 2000). */
export const SOL_S = 88775.244;
/** One hour of LMST, s. */
export const LMST_HOUR_S = SOL_S / 24;

// Below a microsecond of clock: a time computed as a whole minute (a tick at m / 60 h) is
// shown as that minute, not the one before.
const EPSILON_S = 1e-6;

/**
 * LMST hours as "hh:mm:ss" (or "hh:mm" with seconds false), truncated as a clock reads,
 * and wrapped into [0, 24) h.
 * @param {number} lmst_h
 * @param {{seconds?: boolean}} [options]
 */
export function lmstText(lmst_h, { seconds = true } = {}) {
  const total = Math.floor(lmst_h * 3600 + EPSILON_S);
  const day = ((total % 86400) + 86400) % 86400;
  const two = (n) => String(n).padStart(2, "0");
  const hm = `${two(Math.floor(day / 3600))}:${two(Math.floor((day % 3600) / 60))}`;
  return seconds ? `${hm}:${two(day % 60)}` : hm;
}

/** The LMST hours at TT seconds `t_s`, from a moment of the same sol `start` ({t_s, lmst_h});
 * beyond the sol's midnight it goes on past 24. */
export function lmstAt(t_s, start) {
  return start.lmst_h + (t_s - start.t_s) / LMST_HOUR_S;
}
