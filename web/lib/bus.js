// The console's event bus: the panels talk to each other only through it, never by
// reaching into one another. Events (value):
// "may-read" (nothing: this tab may read, at page load or after a sign-in),
// "start" (nothing: the console has begun reading, once), "rover" (the rover picked),
// "me" (who is signed in, or null: emitted at every role refresh), "frame" (each live
// frame, and the /state poll's), "notice" (each typed WebSocket message: {type: "alarm" |
// "command" | ...}), "state" (each /state poll's body), "live" (the rover whose telemetry
// WebSocket opened: subscribed, so what a REST read made from now on misses comes over it),
// "focus" ({sol, t_s}: show that moment on the sol timeline), "sol-truth" ({sol, truth}: the
// shown sol's truth summary).

/**
 * A "frame" event's value: the rover's downlink record, and in the truth view the truth
 * record's fields beside it (their types: records.js, made from the schemas).
 * @typedef {import("./records.js").Downlink & Partial<import("./records.js").Truth>} Frame
 */

const listeners = new Map();

export const bus = {
  on(name, fn) {
    if (!listeners.has(name)) listeners.set(name, []);
    listeners.get(name).push(fn);
  },
  // A listener that throws is reported and the others still hear the event.
  emit(name, value) {
    for (const fn of listeners.get(name) || []) {
      try { fn(value); } catch (e) { console.error(`roverops ${name} listener`, e); }
    }
  },
};
