// roverops console: the sol timeline review. A sol's commands, NATE modes, Attitude
// Quality Flags and events as lanes over LMST, with the estimate's errors and the HGA
// pointing margin plotted underneath (uPlot, vendored in /static/vendor/uplot) on the same
// LMST axis, and the sol's telemetry as a CSV download.
// Live: while the shown sol is the rover's current one, frames (console.js's "frame" hook)
// and command notices ("notice" hook, type "command") are appended where they belong (a
// band extended, a command box or event mark added, points pushed to the plots with
// setData) without redrawing the rest; "Follow live" moves to the next sol when the rover
// reaches it. The WebSocket is decimated (server.hub: the newest frame of a batch, with the
// skipped frames' events), so when the rover falls idle the lanes and plots are reconciled
// with storage in place. "focus" ({sol, t_s}, from the event log) shows that sol with the
// hairline at t_s.
// Wrapped in a function: console.js already owns the global names ($, state, api, ...).
(function () {
  "use strict";

  const byId = (id) => document.getElementById(id);
  const MAX_POINTS = 2000; // the plots ask the server for at most about this many frames
  const MIN_SPAN_H = 1 / 60; // a sol with a single frame still gets a minute of axis
  const TICK_MINUTES = [1, 2, 5, 10, 15, 20, 30, 60, 120, 180, 240, 360, 720];
  const TICK_SPACE_PX = 72; // at least this far between LMST labels
  // The plots' y axis is this wide and they have no left padding, so their plotting area
  // starts where the lanes' tracks start (the lane label column has the same width).
  const GUTTER_PX = 72; // = --tl-gutter in console.css
  const RIGHT_PAD_PX = 16;
  const PLOT_HEIGHT_PX = 150;
  const X_AXIS_PX = 30; // room for the hh:mm labels under a plot (uPlot's default is 50)
  const PALETTE = { ink: "#dde6ee", dim: "#8a99a8", line: "#2a3642", zero: "#ff6b6b" };

  const SOL_S = 88775.244; // a Mars mean solar day: LMST advances 24 h in it
  const MAX_PENDING = 5000; // live messages kept while a sol loads

  // span: the sol's [first, last] LMST hours, the x range of the lanes and the plots.
  // sol/timeline: what is shown; lastT: the newest frame shown (t_s); latestSol: the
  // rover's newest sol known; plotData: each plot's uPlot data arrays (appended to live)
  const view = {
    rover: null, span: null, plots: [], plotData: [], generation: 0, sol: null, timeline: null,
    lastT: -Infinity, latestSol: null, loading: false, pending: [], focus: null,
    wasBusy: false, liveFrames: 0, lastPosition: null, lastTruePosition: null, droppedNotices: 0,
  };

  // ---- time formatting --------------------------------------------------------------

  function hhmm(lmst_h) {
    const minutes = Math.round(lmst_h * 60);
    const h = Math.floor(minutes / 60) % 24;
    return `${String(h).padStart(2, "0")}:${String(minutes % 60).padStart(2, "0")}`;
  }

  function hhmmss(lmst_h) {
    const seconds = Math.round(lmst_h * 3600);
    const h = Math.floor(seconds / 3600) % 24;
    const m = Math.floor((seconds % 3600) / 60);
    return `${String(h).padStart(2, "0")}:${String(m).padStart(2, "0")}:${String(seconds % 60).padStart(2, "0")}`;
  }

  // The tick step the plots' x axis takes too (uPlot: the smallest increment that leaves
  // TICK_SPACE_PX between ticks), so the lanes' ticks line up with the plots' grid.
  function tickMinutes(span_h, width_px) {
    return TICK_MINUTES.find((m) => (width_px * m) / (span_h * 60) >= TICK_SPACE_PX) || TICK_MINUTES.at(-1);
  }

  // uPlot rejects increments with more than ~16 decimals (1/60 h has 18): round them.
  const TICK_INCRS_H = TICK_MINUTES.map((m) => Number((m / 60).toFixed(12)));

  // ---- data -------------------------------------------------------------------------

  async function getJson(path) {
    const response = await fetch(path);
    if (!response.ok) {
      let detail = response.statusText;
      try { detail = (await response.json()).detail; } catch (_) { /* not JSON */ }
      throw new Error(`${path}: ${response.status} ${typeof detail === "string" ? detail : JSON.stringify(detail)}`);
    }
    return response.json();
  }

  function telemetryPath(rover, timeline) {
    const t0 = timeline.start.t_s, t1 = timeline.end.t_s;
    const every = Math.min(86400, Math.max(0, (t1 - t0) / MAX_POINTS));
    const query = new URLSearchParams({
      from: String(t0), to: String(t1), every: every.toFixed(3), limit: String(2 * MAX_POINTS),
    });
    return `/api/rovers/${encodeURIComponent(rover)}/telemetry?${query}`;
  }

  function csvPath(rover, sol) {
    return `/api/rovers/${encodeURIComponent(rover)}/sols/${sol}/telemetry.csv`;
  }

  // ---- the sol picker ---------------------------------------------------------------

  async function fillSols({ followLatest }) {
    const picker = byId("timeline-sol");
    const sols = await getJson(`/api/rovers/${encodeURIComponent(view.rover)}/sols`);
    const previous = Number(picker.value);
    const wasLatest = picker.options.length > 0 && picker.selectedIndex === picker.options.length - 1;
    picker.replaceChildren(...sols.map((s) => new Option(`Sol ${s}`, String(s))));
    if (!sols.length) return null;
    view.latestSol = Math.max(view.latestSol ?? -1, sols.at(-1));
    const keep = !followLatest && !wasLatest && sols.includes(previous);
    picker.value = String(keep ? previous : sols.at(-1));
    return Number(picker.value);
  }

  // A load takes the live messages that arrive meanwhile (view.pending) and applies them
  // once it has drawn: none is lost, none drawn twice (older than lastT: skipped).
  function beginLoad() {
    view.loading = true;
    return ++view.generation; // a later load makes this one's answers stale
  }

  function endLoad(generation) {
    if (generation !== view.generation) return;
    view.loading = false;
    const pending = view.pending;
    view.pending = [];
    for (const [kind, message] of pending) (kind === "frame" ? onFrame : onCommand)(message);
  }

  async function reload({ followLatest }) {
    const rover = byId("rover").value;
    if (!rover) return;
    const generation = beginLoad();
    if (rover !== view.rover) { view.latestSol = null; view.pending = []; }
    view.rover = rover;
    setStatus("Loading…");
    try {
      const sol = await fillSols({ followLatest });
      if (generation !== view.generation) return;
      if (sol === null) showEmpty(`No telemetry yet for ${rover}.`);
      else await loadSol(sol, generation);
    } catch (err) {
      if (generation === view.generation) setStatus(`Could not load the timeline: ${err.message}`, true);
    }
    endLoad(generation);
  }

  async function showSol(sol) {
    const generation = beginLoad();
    const picker = byId("timeline-sol");
    if (![...picker.options].some((o) => Number(o.value) === sol)) {
      picker.append(new Option(`Sol ${sol}`, String(sol)));
    }
    picker.value = String(sol);
    try {
      await loadSol(sol, generation);
    } catch (err) {
      if (generation === view.generation) setStatus(`Could not load the timeline: ${err.message}`, true);
    }
    endLoad(generation);
  }

  function pickSol() { return showSol(Number(byId("timeline-sol").value)); }

  async function fetchSol(sol) {
    const rover = view.rover;
    const timeline = await getJson(`/api/rovers/${encodeURIComponent(rover)}/sols/${sol}/timeline`);
    const frames = await getJson(telemetryPath(rover, timeline));
    return { timeline, frames };
  }

  async function loadSol(sol, generation) {
    setStatus("Loading…");
    const { timeline, frames } = await fetchSol(sol);
    if (generation !== view.generation) return;
    const x0 = timeline.start.lmst_h;
    view.span = [x0, Math.max(timeline.end.lmst_h, x0 + MIN_SPAN_H)];
    const rover = view.rover;
    view.sol = sol;
    view.timeline = timeline;
    view.lastT = Math.max(timeline.end.t_s, frames.length ? frames.at(-1).t_s : -Infinity);
    view.liveFrames = 0;
    view.lastPosition = frames.length ? frames.at(-1).p_mission_est : null;
    view.lastTruePosition = frames.length ? frames.at(-1).p_mission_true : null;
    if (view.focus && view.focus.sol !== sol) view.focus = null;
    const link = byId("timeline-csv");
    link.href = csvPath(rover, sol);
    link.setAttribute("download", `${rover}_sol${sol}.csv`);
    link.removeAttribute("aria-disabled");
    byId("timeline-panel").classList.remove("empty");
    showSummary(timeline);
    applySpan();
    drawLanes(timeline);
    drawPlots(frames);
    placeFocus();
    setStatus(`${frames.length} frames plotted`);
  }

  function showEmpty(message) {
    view.span = null;
    view.sol = null;
    view.timeline = null;
    const link = byId("timeline-csv");
    link.removeAttribute("href");
    link.setAttribute("aria-disabled", "true");
    byId("timeline-panel").classList.add("empty");
    byId("timeline-summary").replaceChildren();
    for (const lane of Object.values(LANES)) byId(lane.id).replaceChildren();
    byId("lane-axis").replaceChildren();
    destroyPlots();
    setStatus(message);
  }

  function setStatus(text, bad = false) {
    const status = byId("timeline-status");
    status.textContent = text;
    status.className = bad ? "timeline-status bad" : "timeline-status";
  }

  // ---- summary ----------------------------------------------------------------------

  function fixed(value, digits, unit) {
    return value === null || value === undefined ? "—" : `${value.toFixed(digits)}${unit}`;
  }

  function showSummary(timeline) {
    const s = timeline.summary;
    const parts = [
      [`Sol ${timeline.sol}, ${hhmmss(timeline.start.lmst_h)}–${hhmmss(timeline.end.lmst_h)} LMST`, ""],
      [`${s.commands} command${s.commands === 1 ? "" : "s"} (${s.commands_failed} not completed)`, s.commands_failed ? "bad" : ""],
      [`${fixed(s.distance_m, 2, " m")} driven (estimated)`, ""],
      [`max IMU time ${fixed(s.max_imu_integration_s, 0, " s")}`, ""],
      [`${s.frames} frames`, ""],
    ];
    // the sol's truth part (in the truth view only) is the Truth panel's (truth.js)
    roverops.emit("sol-truth", { sol: timeline.sol, truth: timeline.truth || null });
    byId("timeline-summary").replaceChildren(...parts.map(([text, cls]) => {
      const span = document.createElement("span");
      span.textContent = text;
      if (cls) span.className = cls;
      return span;
    }));
  }

  // ---- lanes (absolutely positioned divs over the sol's span) -----------------------
  // Each element carries its LMST start and end as CSS variables (--s, --e) and the lanes
  // box the span (--x0, --w): console.css turns them into left and width, so when the span
  // grows live only the two variables change and no element is touched.

  function percent(lmst_h) {
    const [x0, x1] = view.span;
    return (100 * (lmst_h - x0)) / (x1 - x0);
  }

  function applySpan() {
    const lanes = byId("timeline-lanes");
    if (!view.span) return;
    lanes.style.setProperty("--x0", String(view.span[0]));
    lanes.style.setProperty("--w", String(view.span[1] - view.span[0]));
  }

  function setEnd(el, endH) { el.style.setProperty("--e", String(endH)); }

  function placed(className, startH, endH) {
    const el = document.createElement("div");
    el.className = `${className} tl-placed`;
    el.style.setProperty("--s", String(startH));
    setEnd(el, endH);
    return el;
  }

  function marked(className, atH) {
    const el = document.createElement("div");
    el.className = `${className} tl-at`;
    el.style.setProperty("--s", String(atH));
    return el;
  }

  function withLabel(el, text) {
    const label = document.createElement("span");
    label.className = "tl-label";
    label.textContent = text;
    el.appendChild(label);
    return el;
  }

  // Events as the REST timeline gives them ({t_s, lmst_h, text, kind, severity}); a live
  // frame's event is {text, kind, severity, t_s, sol, lmst_h} (or, from an older server, a
  // string: then it takes the frame's time).
  function liveEvent(e, f) {
    if (typeof e === "string") return { t_s: f.t_s, lmst_h: f.lmst_h, sol: f.sol, text: e };
    return { ...e, t_s: e.t_s ?? f.t_s, lmst_h: e.lmst_h ?? f.lmst_h, sol: e.sol ?? f.sol };
  }

  const eventKey = (e) => `${e.t_s.toFixed(3)}|${e.text}`;

  // Commands: one box per stored command (by id; a run again after a restart replaces it).
  function commandBar(c) {
    const bar = placed(`tl-command status-${c.status}`, c.start.lmst_h, c.end.lmst_h);
    bar.dataset.testid = "timeline-command";
    bar.dataset.status = c.status;
    bar.dataset.id = String(c.id);
    bar.dataset.sig = JSON.stringify([c.status, c.reason, c.start.t_s, c.end.t_s, c.reruns, c.submitted_by]);
    const reason = c.reason ? `: ${c.reason}` : "";
    const by = c.submitted_by ? `\nsent by ${c.submitted_by}` : "";
    const rerun = c.reruns ? `\nrun again after a restart (${c.reruns}×)` : "";
    bar.title = `${c.command}\n${c.status}${reason}\n${hhmmss(c.start.lmst_h)}–${hhmmss(c.end.lmst_h)} LMST${by}${rerun}`;
    return withLabel(bar, c.command);
  }

  const commandLane = {
    id: "lane-commands",
    draw(timeline) { byId(this.id).replaceChildren(...timeline.commands.map(commandBar)); },
    command(c) {
      const track = byId(this.id);
      const bar = commandBar(c);
      const old = track.querySelector(`[data-id="${c.id}"]`);
      if (!old) track.appendChild(bar);
      else if (old.dataset.sig !== bar.dataset.sig) old.replaceWith(bar);
    },
  };

  // NATE mode and AQF: bands, one per interval; live, the last one grows or a new starts.
  function band(kind, testid, interval) {
    const seg = placed(`tl-seg tl-${kind}-seg ${kind}-${interval.value}`, interval.start.lmst_h, interval.end.lmst_h);
    seg.dataset.testid = testid;
    seg.dataset.value = interval.value;
    seg.dataset.start = String(interval.start.lmst_h);
    bandTitle(seg, interval.start.lmst_h, interval.end.lmst_h);
    return withLabel(seg, interval.value);
  }

  function bandTitle(seg, startH, endH) {
    seg.title = `${seg.dataset.value}\n${hhmmss(startH)}–${hhmmss(endH)} LMST`;
  }

  function bandLane(id, kind, testid, intervalsKey, frameKey) {
    return {
      id,
      draw(timeline) { byId(id).replaceChildren(...timeline[intervalsKey].map((i) => band(kind, testid, i))); },
      frame(f) {
        const track = byId(id);
        const last = track.lastElementChild;
        if (last) {
          setEnd(last, f.lmst_h);
          bandTitle(last, Number(last.dataset.start), f.lmst_h);
          if (last.dataset.value === String(f[frameKey])) return;
        }
        track.appendChild(band(kind, testid, { value: f[frameKey], start: f, end: f }));
      },
      // Storage's intervals (the WebSocket may have skipped short ones): the bands that
      // agree stay, the first that differs and those after it are replaced.
      reconcile(timeline) {
        const track = byId(id);
        const intervals = timeline[intervalsKey];
        const old = [...track.children];
        let i = 0;
        while (i < intervals.length && i < old.length && old[i].dataset.value === String(intervals[i].value)
               && Math.abs(Number(old[i].dataset.start) - intervals[i].start.lmst_h) < 1e-6) {
          setEnd(old[i], intervals[i].end.lmst_h);
          bandTitle(old[i], intervals[i].start.lmst_h, intervals[i].end.lmst_h);
          i++;
        }
        for (const el of old.slice(i)) el.remove();
        track.append(...intervals.slice(i).map((iv) => band(kind, testid, iv)));
      },
    };
  }

  // Events at the same instant share one mark (its tooltip lists them all), so no mark
  // hides another under the pointer; the mark takes the worst severity of its events.
  // Visual odometry steps get their own lane.
  const VO_EVENT = /^VO step \d+\/\d+/;
  const SEVERITY_RANK = { info: 0, warning: 1, error: 2 };

  function eventMark(e) {
    const mark = marked("tl-event", e.lmst_h);
    mark.dataset.testid = "timeline-event";
    mark.dataset.t = e.t_s.toFixed(3);
    mark.dataset.keys = "";
    return mark;
  }

  const eventLane = {
    id: "lane-events",
    wants: (e) => !VO_EVENT.test(e.text),
    draw(timeline) {
      byId(this.id).replaceChildren();
      for (const e of timeline.events) if (this.wants(e)) this.event(e);
    },
    event(e) {
      const track = byId(this.id);
      const key = e.t_s.toFixed(3);
      let mark = track.querySelector(`[data-t="${key}"]`);
      if (!mark) { mark = eventMark(e); mark.dataset.lmst = String(e.lmst_h); track.appendChild(mark); }
      const texts = mark.dataset.texts ? JSON.parse(mark.dataset.texts) : [];
      texts.push(e.text);
      mark.dataset.texts = JSON.stringify(texts);
      const worst = mark.dataset.severity || "info"; // the mark takes its worst event's
      if ((SEVERITY_RANK[e.severity] || 0) > SEVERITY_RANK[worst] || !mark.dataset.severity) {
        mark.dataset.severity = (SEVERITY_RANK[e.severity] || 0) > SEVERITY_RANK[worst] ? e.severity : worst;
        mark.className = mark.className.replace(/ ?sev-\w+/g, "") + ` sev-${mark.dataset.severity}`;
      }
      mark.title = `${hhmmss(Number(mark.dataset.lmst))} LMST\n${texts.join("\n")}`;
    },
  };

  const voLane = {
    id: "lane-vo",
    wants: (e) => VO_EVENT.test(e.text),
    draw(timeline) {
      byId(this.id).replaceChildren();
      for (const e of timeline.events) if (this.wants(e)) this.event(e);
    },
    event(e) {
      const failed = e.text.includes("failed");
      const mark = marked(`tl-vo ${failed ? "vo-failure" : "vo-update"}`, e.lmst_h);
      mark.dataset.testid = "timeline-vo";
      mark.dataset.value = failed ? "failure" : "update";
      mark.title = `${hhmmss(e.lmst_h)} LMST\n${e.text}`;
      byId(this.id).appendChild(mark);
    },
  };

  // The Alarms lane (server.alarms): a bar per active span of each alarm, raised (or raised
  // again) to cleared (or the sol's end, moving on live), so a span where the channel was
  // normal shows no bar; coloured by level, hatched for a truth-view channel. Placed by t_s,
  // since an alarm may have been raised on an earlier sol (LMST hours repeat each sol).
  // Alarm notices replace the sol's alarm by id and redraw this lane only.
  const LMST_HOUR_S = 88775.244 / 24; // a mean solar sol, s
  const ALARM_ROW_PX = 14;
  const spansOf = (a) => a.spans || [{ from_t_s: a.raised.t_s, to_t_s: a.cleared ? a.cleared.t_s : null }];

  const alarmLane = {
    id: "lane-alarms",
    at(t_s) { return view.timeline.start.lmst_h + (t_s - view.timeline.start.t_s) / LMST_HOUR_S; },
    draw(timeline) {
      const lane = byId(this.id);
      const alarms = timeline.alarms || [];
      const ends = []; // alarms that overlap in time go on rows of their own
      const rows = alarms.map((a) => {
        let row = ends.findIndex((e) => e <= a.raised.t_s);
        if (row < 0) row = ends.push(0) - 1;
        ends[row] = a.cleared ? a.cleared.t_s : Infinity;
        return row;
      });
      lane.style.height = `${Math.max(2, ends.length) * ALARM_ROW_PX + 2}px`;
      lane.replaceChildren(...alarms.flatMap((a, i) => spansOf(a)
        .filter((s) => s.to_t_s === null || s.to_t_s >= timeline.start.t_s)
        .map((s) => this.bar(a, s, rows[i], timeline))));
    },
    bar(a, span, row, timeline) {
      const open = span.to_t_s === null;
      const end = open ? timeline.end.t_s : span.to_t_s;
      const bar = placed(`tl-alarm level-${a.level}${a.truth ? " truth" : ""}`, this.at(span.from_t_s), this.at(end));
      bar.style.top = `${1 + ALARM_ROW_PX * row}px`;
      bar.style.height = `${ALARM_ROW_PX - 2}px`;
      bar.dataset.testid = "timeline-alarm";
      bar.dataset.alarmId = a.id;
      bar.dataset.level = a.level;
      bar.dataset.channel = a.channel;
      bar.dataset.open = open ? "1" : "";
      bar.dataset.fromTs = span.from_t_s;
      bar.dataset.toTs = open ? "" : span.to_t_s;
      const cleared = open ? "not cleared" : `cleared ${hhmmss(this.at(span.to_t_s) % 24)} LMST`;
      const ack = a.acknowledged ? `acknowledged by ${a.acknowledged.by}` : "not acknowledged";
      bar.title = `${a.level.toUpperCase()}${a.truth ? " (truth view)" : ""}: ${a.message}\n` +
        `raised sol ${a.raised.sol} ${hhmmss(a.raised.lmst_h)} LMST (${a.raised.utc} UTC)` +
        `${a.violations > 1 ? `, ${a.violations} violations` : ""}\nthis span ${hhmmss(this.at(span.from_t_s) % 24)} LMST, ${cleared}; ${ack}`;
      return withLabel(bar, a.channel);
    },
    frame(f) { // an alarm not cleared reaches to the newest frame
      for (const bar of byId(this.id).querySelectorAll("[data-open='1']")) setEnd(bar, f.lmst_h);
    },
    alarm(a) {
      const alarms = view.timeline.alarms || (view.timeline.alarms = []);
      const known = alarms.findIndex((k) => k.id === a.id);
      if (known >= 0) alarms[known] = a;
      else if (a.raised.t_s <= view.timeline.end.t_s + LMST_HOUR_S && (!a.cleared || a.cleared.t_s >= view.timeline.start.t_s)) alarms.push(a);
      else return;
      this.draw(view.timeline);
    },
    reconcile(timeline) { view.timeline.alarms = timeline.alarms; this.draw(timeline); },
  };

  // The lanes, top to bottom. Each draws itself from a sol's timeline (draw), and may take
  // live frames (frame), events (event: those it wants), commands (command) and storage's
  // word after live updates (reconcile). A new lane is one more entry.
  const LANES = {
    commands: commandLane,
    nate: bandLane("lane-nate", "nate", "timeline-nate", "nate_modes", "nate_mode"),
    aqf: bandLane("lane-aqf", "aqf", "timeline-aqf", "aqf", "aqf"),
    events: eventLane,
    vo: voLane,
    alarms: alarmLane,
  };

  // Events already drawn (by time and text): a live event storage also gave is not redrawn.
  const seenEvents = new Set();

  function addEvent(e) {
    const key = eventKey(e);
    if (seenEvents.has(key)) return;
    seenEvents.add(key);
    for (const lane of Object.values(LANES)) {
      if (lane.event && (!lane.wants || lane.wants(e))) lane.event(e);
    }
  }

  function drawAxis() {
    const track = byId("lane-axis");
    if (!view.span) { track.replaceChildren(); return; }
    const [x0, x1] = view.span;
    const step = tickMinutes(x1 - x0, track.clientWidth || 600);
    const ticks = [];
    for (let m = Math.ceil((x0 * 60) / step) * step; m <= x1 * 60 + 1e-9; m += step) {
      const tick = document.createElement("div");
      tick.className = "tl-tick";
      tick.style.left = `${percent(m / 60)}%`;
      tick.textContent = hhmm(m / 60);
      ticks.push(tick);
    }
    track.replaceChildren(...ticks);
  }

  // A label shows only when it fits inside its bar; bars change width with the panel.
  function fitLabels() {
    for (const label of byId("timeline-lanes").querySelectorAll(".tl-label")) {
      label.classList.toggle("hidden", label.offsetWidth + 8 > label.parentElement.clientWidth);
    }
  }

  function drawLanes(timeline) {
    seenEvents.clear();
    for (const e of timeline.events) seenEvents.add(eventKey(e));
    for (const lane of Object.values(LANES)) lane.draw(timeline);
    drawAxis();
    fitLabels();
  }

  // ---- plots (uPlot) ----------------------------------------------------------------

  function plotWidth(container) {
    return Math.max(200, Math.floor(container.clientWidth));
  }

  function errorRange(_u, _min, max) {
    const top = max === null || !(max > 0) ? 1 : max * 1.1;
    return [0, top];
  }

  // The margin's range always holds 0, so the line where pointing fails is on screen.
  function marginRange(_u, min, max) {
    const lo = Math.min(min === null ? -1 : min, 0);
    const hi = Math.max(max === null ? 1 : max, 0);
    const pad = Math.max(0.1 * (hi - lo), 0.1);
    return [lo - pad, hi + pad];
  }

  function drawZeroLine(u) {
    const y = Math.round(u.valToPos(0, "y", true));
    const ctx = u.ctx;
    ctx.save();
    ctx.strokeStyle = PALETTE.zero;
    ctx.lineWidth = Math.max(1, devicePixelRatio);
    ctx.setLineDash([6 * devicePixelRatio, 4 * devicePixelRatio]);
    ctx.beginPath();
    ctx.moveTo(u.bbox.left, y);
    ctx.lineTo(u.bbox.left + u.bbox.width, y);
    ctx.stroke();
    ctx.restore();
  }

  // The hairline follows the pointer over the plots; away from them it stays where the
  // last "focus" put it (or hides).
  function moveHairline(u) {
    const left = u.cursor.left;
    if (left === undefined || left < 0 || !view.span) { placeFocus(); return; }
    setHairline(u.posToVal(left, "x"), false);
  }

  function setHairline(lmst_h, focused) {
    const line = byId("timeline-hairline");
    line.hidden = lmst_h === null;
    line.classList.toggle("focused", focused);
    if (lmst_h !== null) line.style.setProperty("--s", String(lmst_h));
  }

  // LMST at t_s on the shown sol (24 h of LMST per mean solar day).
  function lmstAt(t_s) {
    const start = view.timeline.start;
    return start.lmst_h + ((t_s - start.t_s) / SOL_S) * 24;
  }

  function placeFocus() {
    const f = view.focus;
    const here = f && view.timeline && f.sol === view.sol;
    const line = byId("timeline-hairline");
    line.dataset.focusTs = here ? String(f.t_s) : "";
    setHairline(here ? lmstAt(f.t_s) : null, Boolean(here));
  }

  // Estimators run beside SAPP (roverops serve --estimators): one more line each on the
  // error plots, from the frames' "estimators" entries.
  const SIDE_COLOURS = { kinematic_ekf: "#ff8c42", radio_ekf: "#e65ac8" };  // as the 3D view's
  const SIDE_KEYS = { "plot-position-error": "position_error_m", "plot-attitude-error": "attitude_error_deg" };

  function sideNames(frames) {
    const names = new Set();
    for (const f of frames) for (const name of Object.keys(f.estimators || {})) names.add(name);
    return [...names].sort();
  }

  function plotOptions(container, spec, sides = []) {
    const axis = { stroke: PALETTE.dim, grid: { stroke: PALETTE.line, width: 1 }, ticks: { stroke: PALETTE.line, width: 1 } };
    const hooks = { setCursor: [moveHairline] };
    if (spec.zeroLine) hooks.draw = [drawZeroLine];
    return {
      title: spec.title,
      width: plotWidth(container),
      height: PLOT_HEIGHT_PX,
      padding: [10, RIGHT_PAD_PX, 0, 0],
      cursor: { sync: { key: "sol-timeline" }, drag: { x: false, y: false } },
      scales: { x: { time: false, range: () => view.span }, y: { range: spec.range } },
      axes: [
        { ...axis, size: X_AXIS_PX, incrs: TICK_INCRS_H, space: TICK_SPACE_PX, values: (_u, splits) => splits.map(hhmm) },
        { ...axis, size: GUTTER_PX },
      ],
      series: [
        { label: "LMST", value: (_u, v) => (v === null ? "—" : hhmmss(v)) },
        {
          label: spec.label, stroke: spec.color, width: 1.5,
          value: (_u, v) => (v === null ? "—" : `${v.toFixed(spec.digits)} ${spec.unit}`),
        },
        ...sides.map((name) => ({
          label: name, stroke: SIDE_COLOURS[name] || "#d98cff", width: 1.5,
          value: (_u, v) => (v === null ? "—" : `${v.toFixed(spec.digits)} ${spec.unit}`),
        })),
      ],
      hooks,
    };
  }

  const PLOTS = [
    {
      id: "plot-position-error", title: "Position error (m)", label: "position error",
      unit: "m", digits: 3, color: "#3d8bfd", range: errorRange,
      value: (f) => f.position_error_m,
    },
    {
      id: "plot-attitude-error", title: "Attitude error (deg)", label: "attitude error",
      unit: "°", digits: 3, color: "#6bd48a", range: errorRange,
      value: (f) => f.attitude_error_deg,
    },
    {
      id: "plot-hga-margin", title: "HGA pointing margin (deg)", label: "HGA margin",
      unit: "°", digits: 2, color: "#f0b429", range: marginRange, zeroLine: true,
      // no margin while Earth is below the horizon: a gap in the line
      value: (f) => (f.earth_up && f.hga_margin_deg !== null ? f.hga_margin_deg : null),
    },
  ];

  function destroyPlots() {
    for (const plot of view.plots) plot.destroy();
    view.plots = [];
    view.plotData = [];
  }

  const sideValue = (f, name, key) => {
    const e = (f.estimators || {})[name];
    return e && e[key] !== undefined ? e[key] : null;
  };

  // Each plot's uPlot data: [x, its value, the estimators' values beside SAPP].
  function plotSeries(frames, spec, sides) {
    const key = SIDE_KEYS[spec.id];
    const ys = frames.map((f) => { const v = spec.value(f); return v === undefined ? null : v; });
    return [frames.map((f) => f.lmst_h), ys, ...sides.map((name) => frames.map((f) => sideValue(f, name, key)))];
  }

  function drawPlots(frames) {
    destroyPlots();
    const names = sideNames(frames);
    for (const spec of PLOTS) {
      const container = byId(spec.id);
      const key = SIDE_KEYS[spec.id];
      // an estimator of position only (radio_ekf) has no attitude line
      const sides = key ? names.filter((name) => frames.some((f) => sideValue(f, name, key) !== null)) : [];
      const data = plotSeries(frames, spec, sides);
      view.plotData.push({ spec, sides, data });
      view.plots.push(new uPlot(plotOptions(container, spec, sides), data, container));
    }
  }

  // A live frame's points, pushed onto the plots' arrays (setData at the next render).
  function appendPlots(f) {
    for (const { spec, sides, data } of view.plotData) {
      plotSeries([f], spec, sides).forEach((column, i) => data[i].push(column[0]));
    }
  }

  // Storage's frames in place of what was plotted live (the same plots, new data).
  function reconcilePlots(frames) {
    view.plotData.forEach((entry, i) => {
      entry.data = plotSeries(frames, entry.spec, entry.sides);
      view.plots[i].setData(entry.data);
    });
  }

  // ---- resizing ---------------------------------------------------------------------

  let resizeQueued = false;
  function resize() {
    if (resizeQueued) return;
    resizeQueued = true;
    requestAnimationFrame(() => {
      resizeQueued = false;
      for (const plot of view.plots) {
        const container = plot.root.parentElement;
        const width = plotWidth(container);
        if (width !== plot.width) plot.setSize({ width, height: PLOT_HEIGHT_PX });
      }
      if (view.span) { drawAxis(); fitLabels(); }
    });
  }

  // ---- live -------------------------------------------------------------------------

  // One render per animation frame, however many messages came: the span's variables,
  // the plots' new data, the axis and the summary.
  let renderQueued = false;
  function render() {
    if (renderQueued) return;
    renderQueued = true;
    requestAnimationFrame(() => {
      renderQueued = false;
      if (!view.timeline) return;
      applySpan();
      view.plotData.forEach((entry, i) => view.plots[i].setData(entry.data));
      drawAxis();
      fitLabels();
      showSummary(view.timeline);
      setStatus(`live: ${view.liveFrames} frame${view.liveFrames === 1 ? "" : "s"} added since loading`);
    });
  }

  const following = () => byId("timeline-follow").checked;
  const showingLatest = () => view.sol !== null && view.sol === view.latestSol;

  // The rover reached a sol the picker does not have: offer it, and show it if the
  // operator was following the current sol (an older sol on screen is left alone).
  function newSol(sol) {
    const wasLatest = showingLatest() || view.timeline === null;
    view.latestSol = sol;
    const picker = byId("timeline-sol");
    if (![...picker.options].some((o) => Number(o.value) === sol)) {
      picker.append(new Option(`Sol ${sol}`, String(sol)));
    }
    if (wasLatest && following()) showSol(sol);
  }

  function onFrame(f) {
    if (!view.rover || roverops.state.rover !== view.rover) return;
    if (view.loading) {
      if (view.pending.length < MAX_PENDING) view.pending.push(["frame", f]);
      return;
    }
    if (view.latestSol === null || f.sol > view.latestSol) {
      newSol(f.sol);
      if (view.loading) { view.pending.push(["frame", f]); return; }
    }
    if (!view.timeline || f.sol !== view.sol) return;
    if (f.t_s > view.lastT) appendFrame(f);
    else if (f.events && f.events.length) { addFrameEvents(f); render(); } // a frame the /state poll showed first
  }

  function addFrameEvents(f) {
    for (const e of f.events || []) {
      const event = liveEvent(e, f);
      if (event.sol === view.sol) addEvent(event);
    }
  }

  function appendFrame(f) {
    view.lastT = f.t_s;
    view.liveFrames += 1;
    view.span[1] = Math.max(view.span[1], f.lmst_h);
    view.timeline.end = { t_s: f.t_s, lmst_h: f.lmst_h };
    for (const lane of Object.values(LANES)) if (lane.frame) lane.frame(f);
    addFrameEvents(f);
    appendPlots(f);
    summarise(f);
    render();
  }

  // The summary's figures, moved on by one frame (storage's on the next load).
  function summarise(f) {
    const s = view.timeline.summary;
    const more = (a, b) => (a === null || a === undefined ? b : Math.max(a, b));
    if (Number.isFinite(f.imu_integration_s)) s.max_imu_integration_s = more(s.max_imu_integration_s, f.imu_integration_s);
    s.distance_m += step(view.lastPosition, f.p_mission_est);
    view.lastPosition = f.p_mission_est;
    const t = view.timeline.truth;
    if (!t) return;
    if (Number.isFinite(f.position_error_m)) t.max_position_error_m = more(t.max_position_error_m, f.position_error_m);
    if (Number.isFinite(f.attitude_error_deg)) t.max_attitude_error_deg = more(t.max_attitude_error_deg, f.attitude_error_deg);
    if (f.earth_up && Number.isFinite(f.hga_margin_deg)) {
      t.min_hga_margin_deg = t.min_hga_margin_deg === null ? f.hga_margin_deg : Math.min(t.min_hga_margin_deg, f.hga_margin_deg);
    }
    t.distance_m += step(view.lastTruePosition, f.p_mission_true);
    view.lastTruePosition = f.p_mission_true;
  }

  // The horizontal step between two positions (0 when either is missing), m.
  function step(last, now) {
    return last && now ? Math.hypot(now[0] - last[0], now[1] - last[1]) : 0;
  }

  // A command the rover reported (a "command" notice, as the timeline lists it).
  function onCommand(c) {
    if (!view.rover || roverops.state.rover !== view.rover) return;
    if (view.loading) {
      if (view.pending.length < MAX_PENDING) view.pending.push(["command", c]);
      return;
    }
    if (!view.timeline || !showingLatest() || c.end.t_s < view.timeline.start.t_s) return;
    const known = view.timeline.commands.findIndex((k) => k.id === c.id);
    if (known >= 0) view.timeline.commands[known] = c;
    else view.timeline.commands.push(c);
    const s = view.timeline.summary;
    s.commands = view.timeline.commands.length;
    s.commands_failed = view.timeline.commands.filter((k) => k.status !== "completed").length;
    for (const lane of Object.values(LANES)) if (lane.command) lane.command(c);
    view.wasBusy = true; // the command may have run between two /state polls
    render();
  }

  // An alarm raised, escalated, acknowledged or cleared (an "alarm" notice).
  function onAlarm(a) {
    if (!view.rover || a.rover !== view.rover || view.loading || !view.timeline || !showingLatest()) return;
    alarmLane.alarm(a);
    render();
  }

  // The rover fell idle after work: storage's word on the sol, patched in place (the
  // WebSocket's decimation may have skipped short modes and points).
  async function reconcile() {
    if (!view.timeline || !showingLatest() || view.loading) return;
    const generation = view.generation;
    const { timeline, frames } = await fetchSol(view.sol);
    if (generation !== view.generation || view.loading) return;
    for (const c of timeline.commands) LANES.commands.command(c);
    for (const lane of Object.values(LANES)) if (lane.reconcile) lane.reconcile(timeline);
    for (const e of timeline.events) addEvent(e);
    view.span[1] = Math.max(view.span[1], timeline.end.lmst_h);
    view.lastT = Math.max(view.lastT, timeline.end.t_s);
    view.timeline = { ...timeline, end: view.lastT > timeline.end.t_s ? view.timeline.end : timeline.end };
    reconcilePlots(frames);
    const panel = byId("timeline-panel");
    panel.dataset.reconciled = String(Number(panel.dataset.reconciled || 0) + 1); // for tests
    render();
  }

  function onState(s) {
    if (!view.rover || s.rover !== view.rover) return;
    const busy = Boolean(s.executing) || s.queue.length > 0;
    if (view.wasBusy && !busy) reconcile().catch((err) => setStatus(`Could not reconcile: ${err.message}`, true));
    view.wasBusy = busy;
  }

  // ---- start ------------------------------------------------------------------------

  function start() {
    byId("rover").addEventListener("change", () => reload({ followLatest: true }));
    byId("timeline-sol").addEventListener("change", pickSol);
    byId("timeline-refresh").addEventListener("click", () => reload({ followLatest: false }));
    byId("timeline-follow").addEventListener("change", () => {
      if (following() && !showingLatest()) reload({ followLatest: true });
    });
    window.addEventListener("resize", resize);
    // the panel also changes width without a window resize (a scrollbar comes or goes)
    new ResizeObserver(resize).observe(byId("timeline-panel"));
    byId("timeline-hairline").hidden = true;
    roverops.on("frame", onFrame);
    roverops.on("notice", (n) => {
      // notices were lost (a client far behind): storage's word once the rover is idle
      if ((n.dropped_notices || 0) > view.droppedNotices) { view.droppedNotices = n.dropped_notices; view.wasBusy = true; }
      if (n.type === "command") onCommand(n.command);
      if (n.type === "alarm") onAlarm(n.alarm);
    });
    roverops.on("state", onState);
    // a sign-in or out may change whether the timeline has its truth part: read it again
    let seesTruth = Boolean(roverops.state.me && roverops.state.me.sees_truth);
    roverops.on("me", (me) => {
      const sees = Boolean(me && me.sees_truth);
      if (sees === seesTruth) return;
      seesTruth = sees;
      if (view.sol !== null) showSol(view.sol);
    });
    roverops.on("focus", ({ sol, t_s }) => {
      view.focus = { sol, t_s };
      if (view.sol === sol && view.timeline) placeFocus();
      else showSol(sol);
    });
    reload({ followLatest: true });
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

  whenRoverKnown(start);
})();
