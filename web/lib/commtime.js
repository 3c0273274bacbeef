// The link across light time in words (issue 23): light time, durations, how long ago,
// how soon a window opens, a moment of the rover's clock, data volumes. Pure functions
// (tests/js/commtime.test.mjs); the server sends TT seconds, LMST hours and Mbit.
import { lmstText } from "./marstime.js";

const two = (n) => String(n).padStart(2, "0");

/** Seconds as a clock reads a duration: "16:58" (min:s), "1:02:03" from an hour up. */
export function clockText(s) {
  const total = Math.max(0, Math.round(s));
  const h = Math.floor(total / 3600), m = Math.floor((total % 3600) / 60), sec = total % 60;
  return h ? `${h}:${two(m)}:${two(sec)}` : `${m}:${two(sec)}`;
}

/** A duration in words, to the minute: "under a minute", "17 min", "1 h 05 min". */
export function durationText(s) {
  const minutes = Math.floor(Math.max(0, s) / 60);
  if (minutes < 1) return "under a minute";
  if (minutes < 60) return `${minutes} min`;
  return `${Math.floor(minutes / 60)} h ${two(minutes % 60)} min`;
}

/** How long ago, in words: "just now" under a minute, "9 min ago", "1 h 05 min ago". */
export function agoText(s) {
  return s < 60 ? "just now" : `${durationText(s)} ago`;
}

/** LMST hours as "hh:mm", to the nearest second first: a window computed to open at 09:00
 * (8.9999999996 h) reads 09:00, not 08:59. */
export function hmText(lmst_h) {
  return lmstText(Math.round(lmst_h * 3600) / 3600, { seconds: false });
}

/** A moment of the rover's clock ({sol, lmst_h}): "sol 412 14:02 LMST". */
export function momentText(m) {
  return `sol ${m.sol} ${hmText(m.lmst_h)} LMST`;
}

/** The newest data on the ground (its moment {sol, lmst_h}), received `receivedAgoS` ago
 * by the rover's clock (null: not known): "data of sol 412 14:02 LMST, received 9 min ago". */
export function dataAgeText(data, receivedAgoS) {
  const received = receivedAgoS === null || receivedAgoS === undefined ? "" : `, received ${agoText(receivedAgoS)}`;
  return `data of ${momentText(data)}${received}`;
}

/** Data made at `data` ({sol, lmst_h}) that reached the ground `lateS` after it was made:
 * "data of sol 412 14:02 LMST, received 17 min later". */
export function arrivalText(data, lateS) {
  return `data of ${momentText(data)}, received ${durationText(Math.round(lateS / 60) * 60)} later`;
}

// The least time between the freshest data a relay pass brings and a pass: a pass's length
// and some (sim/comm/plan.py: passes of about 8-12 minutes).
const PASS_MARGIN_S = 15 * 60;

/** How old the newest data may be before the console shows it as stale, s: the freshest a
 * relay pass brings is the orbiter's store-and-forward delay (`plan.relay_latency_s`) and
 * the one-way light time old, and a pass lasts minutes; anything older is behind the link. */
export function staleAfterS(plan, oneWayLightS) {
  return (plan && Number.isFinite(plan.relay_latency_s) ? plan.relay_latency_s : 0) + oneWayLightS + PASS_MARGIN_S;
}

/** Where a window ({start_t_s, end_t_s}) stands at `now_t_s`: "in 12 min", "open, 40 min
 * left", "ended 3 min ago". */
export function untilText(now_t_s, w) {
  if (now_t_s < w.start_t_s) return `in ${durationText(w.start_t_s - now_t_s)}`;
  if (now_t_s < w.end_t_s) return `open, ${durationText(w.end_t_s - now_t_s)} left`;
  return `ended ${agoText(now_t_s - w.end_t_s)}`;
}

/** A data volume given in Mbit: "84.6 Mbit", "0.43 Mbit", "12.5 kbit", "0 bit". */
export function mbitText(mbit) {
  if (!Number.isFinite(mbit) || mbit <= 0) return "0 bit";
  if (mbit >= 10) return `${mbit.toFixed(1)} Mbit`;
  if (mbit >= 0.1) return `${mbit.toFixed(2)} Mbit`;
  return `${Number((mbit * 1000).toPrecision(3))} kbit`;
}

/** How full the onboard store is, percent: "37 %", "2.5 %", "0.004 %". */
export function fillText(pct) {
  if (!(pct > 0)) return "0 %";
  if (pct >= 10) return `${Math.round(pct)} %`;
  return `${Number(pct.toPrecision(2))} %`;
}

/** A window's kind as operators say it. */
export const WINDOW_WORDS = { uplink: "uplink", relay: "relay pass", dte: "direct-to-Earth" };
