// The console's one entry (index.html loads it as a module). Each panel is a module that
// subscribes to the event bus when imported; then the sign-in at page load starts them.
import { bus } from "./lib/bus.js";
import { state } from "./console.js";
import { signInAtLoad } from "./signin.js";
import "./readouts.js";
import "./commanding.js";
import "./sequences.js";
import "./vo_advice.js";
import "./truth.js";
import "./faults.js";
import "./view3d.js";
import "./timeline/panel.js";
import "./plot.js";
import "./alarms.js";
import "./eventlog.js";
import "./queue.js";
import "./comm.js";
import "./images.js";
import "./rehearsal.js";

// The browser tests' hook (tests/browser): the bus, and the console's state (its WebSocket).
window.roverops = { on: bus.on, emit: bus.emit, state };

signInAtLoad();
