"""The rovers the server hosts: each a ``RoverSession`` on its own simulation clock.

A ``RoverRuntime`` owns one rover's session (flight software in the loop, ``sim.loop.session``),
its queue of accepted sequences, and a thread that runs the clock:

- The clock runs at ``speed`` sim s per wall s (1 to ``MAX_SPEED``; ``inf``: flat out); it pauses.
- The next step of the queue starts when its time tag comes (``sequences.language``): an
  LMST tag the next time the rover's LMST reads it, a sol-and-LMST tag at that moment, a
  relative tag that long after the previous command completed, no tag at once. Until then
  the rover waits: at a finite speed the wait is played out in wall time, at ``inf`` it is
  skipped ("idle time is skipped"). With nothing queued the clock keeps running: at a
  finite speed at that speed, at ``inf`` at ``IDLE_SPEED_AT_MAX`` (below).
- A command executes as a whole in the session (a drive takes a few seconds of wall time)
  and its frames are then *played out*: published (WebSocket subscribers, storage) as the
  clock reaches their time. So what is stored and shown never runs ahead of the clock.
  At ``inf`` a command, its play-out (whole, before the checkpoint) and the next step follow
  without a pause; a new sequence or clock change wakes the clock thread from its sleep.
- Immediate commands (``POST .../commands``) run in the order sent, after a started sequence.
- Operators reorder the queue (``move``) and cancel from it (``cancel``) within the rules of
  ``server.queue``; a step starts only if its sequence is still at the head when the clock
  thread takes it up (under ``lock``). Every queue change is applied to the last checkpoint
  at once, and its listener's ``queue_changed`` hears of it (``server.queue_view``).
- A step that fails (its mode ran and failed) is reported and the sequence goes on; a step
  that is refused (it could not run) stops the sequence, which ends ``failed``. A sequence
  that ran to the end is ``completed``, with the failed steps in its ``detail``.

The state (session, queue, clock, play-out, link) is checkpointed as plain data
(``server.storage.checkpoint``) once per wall second through the storage writer, with the
frames published before it; restored, it resumes there: frames published again up to the
last stored (``watermark_t_s``) are dropped, steps run again keep one row each. A clock
change, the operators' intent, is stored before ``set_clock`` returns; ``stop`` checkpoints.

It publishes the downlink, the truth beside it and the images (``server.sinks.FrameBatch``);
``last_frame`` is the newest downlink on the ground, ``reported`` what its events report of
the onboard tables (``server.validation.reported``). Across light time (``server.comm``)
sequences wait for their uplink window, the downlink for a pass, the truth goes out live.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict
from typing import Any

from sequences import commands as cmd
from sequences.language import Sequence, TimeTag
from server.comm.hosting import CancelSent, CommMode, RuntimeComm
from server.queue import (
    Cancelled,
    NotQueuedError,
    QueuedSequence,
    QueueEntry,
    QueueError,
    StepOutcome,
    insert,
    merged,
    moved,
    snapshot,
    start_time,
)
from server.rovers import ROVERS, ClockState, RoverSpec
from server.sinks import FrameBatch, FrameSink, PlayedFrame, RuntimeListener, with_truth
from server.storage.checkpoint import CheckpointFormatError, decode, encode
from server.storage.records import CommandRecord
from server.validation.reported import ReportedState
from sim.loop.downlink import DownlinkDict
from sim.loop.session import RoverSession
from sim.scoring.truth import TruthDict
from sim.world.marsclock import (
    SOL_S,
    get_mission,
    lmst_h_from_t_s,
    sol_number_t_s,
    t_s_to_utc,
)

# the queue's types are the runtime's vocabulary too (``server.queue``)
__all__ = ["ROVERS", "Cancelled", "CheckpointFormatError", "ClockState", "NotQueuedError",
           "QueueEntry", "QueueError", "RoverSpec"]  # fmt: skip

log = logging.getLogger(__name__)

MAX_SPEED = 10_000.0  # largest finite speed factor
TICK_S = 0.05  # wall seconds between clock ticks (none at max speed while work is due)
MAX_TICK_S = 0.25  # wall seconds one tick may account for
# Idle time skipped at max speed goes a sol at a time, so every sol has a frame to show.
IDLE_CHUNK_S = SOL_S
IDLE_STEP_S = 10.0  # at a finite speed the idle rover is simulated in steps this long
# At max speed with nothing queued there is no next step to skip to. The clock does not stop
# (a rover's time passes, and an operator reads a frozen LMST as a hung server): it runs in
# real time until work arrives, and /state says so (``effective_speed``). Faster would
# race through sols while an operator writes the next sequence (at 10,000x a sol takes 9 s
# of wall time), moving the LMST its time tags were written against, and fill the database
# with frames of an idle rover (an articulating one is propagated at 8 Hz); real time costs
# one frame per IDLE_STEP_S.
IDLE_SPEED_AT_MAX = 1.0
MIN_SKIP_S = 1.0  # the least a skip of idle time moves the clock (what is due is never missed)
FRAME_EVERY_S = 1.0  # 8 Hz activity is recorded at most once a simulated second
CHECKPOINT_EVERY_S = 1.0  # wall seconds between checkpoints


class RoverRuntime:
    """One rover on its own clock (module docstring). ``sinks`` receive every frame
    batch as it is played out (``server.sinks``: storage, alarms, WebSocket hub, 3D view);
    ``listener`` (``server.sinks.RuntimeListener``, given when the runtime is built) hears
    of everything else: command reports, sequence status, checkpoints and queue changes.
    Without a listener the runtime runs alone: it neither checkpoints nor reports."""

    def __init__(self, spec: RoverSpec, session: RoverSession | None = None,
                 estimators: tuple[str, ...] = ("sapp",), listener: RuntimeListener | None = None,
                 sinks: Iterable[FrameSink] = (), comm: CommMode = "instant") -> None:  # fmt: skip
        self.spec = spec
        self.listener = listener
        self.estimators = tuple(estimators)
        self.session = session or RoverSession(
            spec.site, spec.seed, spec.start_utc, frame_every_s=FRAME_EVERY_S, estimators=estimators
        )
        self.clock = ClockState()
        self.queue: deque[QueuedSequence] = deque()
        self.lock = threading.RLock()
        self.sinks: list[FrameSink] = list(sinks)  # a 3D view joins and leaves (RoverScene)
        self.executing: str = ""
        self.current_step: tuple[int, int] | None = None  # (sequence id, step) executing
        # (downlink, truth) record pairs still to play out, in time order
        self._playout: deque[PlayedFrame] = deque()
        self._clock_t_s = self.session.sim.t_s  # the published clock (<= the session's)
        self._last_done_t_s = self._clock_t_s
        self._stop = threading.Event()
        self._wake = threading.Event()  # work arrived: the clock thread need not sleep on
        self._thread: threading.Thread | None = None
        self._last_checkpoint_wall = 0.0
        self._last_state: dict[str, Any] | None = None  # the last checkpoint taken (or restored)
        self._clock_changed = False  # since the clock thread's last checkpoint
        self.last_frame: DownlinkDict | None = None  # the latest downlink record played out
        self.last_truth: TruthDict | None = None  # and its truth record
        self.reported = ReportedState()
        self.watermark_t_s = -math.inf  # frames up to here are stored already (restore)
        self.comm = RuntimeComm(self, comm)  # the link across light time (server.comm)

    # ---- control ------------------------------------------------------------------

    @property
    def t_s(self) -> float:
        """The rover's clock (simulated TT seconds from J2000)."""
        return self._clock_t_s

    def start(self) -> None:
        """Start the clock thread."""
        self._thread = threading.Thread(
            target=self._run, name=f"rover-{self.spec.name}", daemon=True
        )
        self._thread.start()

    def stop(self) -> None:
        """Stop the clock thread (at the next tick) and checkpoint the state it stopped in:
        a graceful stop loses nothing, not even the last second."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=30.0)
            if self._thread.is_alive():  # a command still computing: its state is not whole
                log.warning(
                    "rover %s: clock thread still busy; no final checkpoint", self.spec.name
                )
                return
        self.checkpoint()

    def set_clock(self, running: bool | None = None, speed: float | None = None) -> None:
        """Pause/resume and set the speed (validated by the caller). A change is stored
        before this returns: the last checkpoint again, with the new clock (the session
        may be mid-command in the clock thread, so its state is not taken from here); the clock
        thread checkpoints the state the change took effect in at its next tick."""
        with self.lock:
            before = (self.clock.running, self.clock.speed)
            if running is not None:
                self.clock.running = running
            if speed is not None:
                self.clock.speed = speed
            if (self.clock.running, self.clock.speed) == before:
                return
            self._clock_changed = True
            self._wake.set()
            if self._last_state is None or self.listener is None:
                return
            self._save({**self._last_state, "clock": asdict(self.clock)})
        self.listener.commit()

    def enqueue(self, sequence_id: int, sequence: Sequence, immediate: bool = False) -> None:
        """Queue an accepted sequence (across light time: at its next uplink window). An
        immediate command goes before the sequences, after those sent before it."""
        entry = QueuedSequence(sequence_id, sequence, immediate=immediate)
        if self.comm.uplink(entry):
            self._queue_changed(commit=True)
            return
        self.take_onboard(entry)

    def take_onboard(self, entry: QueuedSequence, by_link: bool = False) -> None:
        """Into the rover's queue; ``by_link``: arrived onboard, the clock thread checkpoints."""
        with self.lock:
            items = list(self.queue)
            insert(items, entry)
            self.queue = deque(items)
            if not by_link:
                self._checkpoint_queue()
        self._wake.set()  # its first step may be due now
        self._queue_changed()

    def cancel(self, sequence_id: int) -> Cancelled | CancelSent | None:
        """Drop a queued sequence (a running one stops after its current command): where it
        stopped, or ``None`` if not queued; stored before this returns. Across light time,
        ``RuntimeComm.cancel`` (a cancel may go up: ``CancelSent``)."""
        if self.comm.mission is None:
            return self.cancel_onboard(sequence_id)
        found = self.comm.cancel(sequence_id)
        if found is not None:
            self._queue_changed(commit=True)
        return found

    def cancel_onboard(self, sequence_id: int, by_link: bool = False) -> Cancelled | None:
        """Drop a sequence from the rover's own queue (``cancel``; ``by_link``: as above)."""
        with self.lock:
            item = next((q for q in self.queue if q.sequence_id == sequence_id), None)
            if item is None:
                return None
            self.queue.remove(item)
            running = self.current_step
            stopped = Cancelled(
                steps=len(item.sequence.steps),
                done=min(item.next_step, len(item.sequence.steps)),
                running_step=running[1] if running and running[0] == sequence_id else None,
            )
            if not by_link:
                self._checkpoint_queue(removed=sequence_id)
        self._queue_changed(commit=not by_link)
        return stopped

    def move(self, sequence_id: int, to: int) -> None:
        """Put a queued sequence at position ``to`` (0 is the head); ``QueueError`` saying
        why for a started one or an immediate command, in front of one, past the end."""
        with self.lock:
            items = moved(self.queue, sequence_id, to, self.spec.name)
            if items is None:
                return
            self.queue = deque(items)
            self._checkpoint_queue()
        self._queue_changed(commit=True)

    def queued_ids(self) -> list[int]:
        """Sequence ids in queue order, and those the link holds (waiting, on their way up)."""
        with self.lock:
            return [*self.comm.held_ids(), *(q.sequence_id for q in self.queue)]

    def queue_snapshot(self) -> list[QueueEntry]:  # in order, copied under the lock
        with self.lock:
            return snapshot(self.queue, self.current_step)

    def _checkpoint_queue(self, removed: int | None = None) -> None:
        """A queue change into the last checkpoint, stored (the session may be mid-command in
        the clock thread, so its state is not taken from here: ``server.queue.merged``)."""
        self.amend_checkpoint(lambda last: {"queue": merged(last["queue"], self.queue, removed)})

    def amend_checkpoint(self, change: Callable[[dict[str, Any]], dict[str, Any]]) -> None:
        with self.lock:  # the last checkpoint stored again with change(last)'s parts
            if self._last_state is not None and self.listener is not None:
                self._save({**self._last_state, **change(self._last_state)})

    def _queue_changed(self, commit: bool = False) -> None:
        """Store a queue change at once (``commit``) and tell the listener of it."""
        if self.listener is None:
            return
        if commit and self._last_state is not None:
            self.listener.commit()
        self.listener.queue_changed(self.spec.name)

    # ---- state for the API ----------------------------------------------------------

    def lmst_h(self, t_s: float) -> float:  # LMST at the rover's mission site, hours
        return float(lmst_h_from_t_s(t_s, get_mission(self.spec.mission).lon_west_deg))

    def sol(self, t_s: float) -> int:  # MER sol number at t_s
        return int(sol_number_t_s(self.spec.mission, t_s))

    def clock_text(self) -> str:
        """The rover's clock now as ``sol N hh:mm:ss LMST`` (for the audit log)."""
        t, seconds = self._clock_t_s, int(self.lmst_h(self._clock_t_s) % 24.0 * 3600.0)
        h, rest = divmod(seconds, 3600)
        return f"sol {self.sol(t)} {h:02d}:{rest // 60:02d}:{rest % 60:02d} LMST"

    def state(self) -> dict[str, Any]:
        """A JSON-ready summary: clock, queue, executing command and the last frame."""
        with self.lock:
            t = self._clock_t_s
            return {
                "rover": self.spec.name,
                "site": self.spec.site,
                "mission": self.spec.mission,
                "t_s": t,
                "utc": t_s_to_utc(t).isoformat(),
                "sol": self.sol(t),
                "lmst_h": self.lmst_h(t),
                "clock": {"running": self.clock.running, "speed": _speed_json(self.clock.speed)},
                # what the clock runs at now (at max with nothing queued: real time)
                "effective_speed": _speed_json(self._effective_speed()),
                "executing": self.executing,
                "comm": self.comm.mode,
                "queue": [q.summary() for q in self.queue],
                **self.comm.ground_state(),  # across light time: what the ground knows of them
                "frame": with_truth(self.last_frame, self.last_truth),
            }

    def _effective_speed(self) -> float:
        """The speed the clock runs at now: ``speed``, except at max with nothing queued,
        playing out or on its way (``IDLE_SPEED_AT_MAX``). The caller holds ``lock``."""
        idle = not self.queue and not self._playout and self.comm.next_due_t_s() == math.inf
        if math.isinf(self.clock.speed) and idle:
            return IDLE_SPEED_AT_MAX
        return self.clock.speed

    # ---- the clock thread -------------------------------------------------------------

    def _run(self) -> None:
        wall = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            dt_wall, wall = now - wall, now
            try:
                busy = self._tick(dt_wall)
            except Exception:  # keep the server alive; the rover stops its queue
                log.exception("rover %s: clock tick failed", self.spec.name)
                with self.lock:
                    self.clock.running = False
                busy = False
            if not busy:
                self._wake.wait(TICK_S)
            self._wake.clear()

    def _tick(self, dt_wall: float) -> bool:
        """One step of the clock; True when the next is due at once (at max speed, after a
        command, its play-out or a skip of idle time: a sleep would only add wall time)."""
        self.comm.apply_request()
        try:
            return self._tick_clock(dt_wall)
        finally:
            self.comm.advance(self._clock_t_s)

    def _tick_clock(self, dt_wall: float) -> bool:
        with self.lock:
            running, speed, changed = self.clock.running, self.clock.speed, self._clock_changed
        at_max = running and math.isinf(speed)
        # At max speed a command's frames go out whole in one tick: before the checkpoint,
        # which would otherwise carry all of them (a drive's thousands) in its play-out.
        played = at_max and bool(self._playout)
        if played:
            self._advance_playout(math.inf)
        if changed or (
            running and time.monotonic() - self._last_checkpoint_wall >= CHECKPOINT_EVERY_S
        ):
            self.checkpoint()  # a paused clock is checkpointed once, where it stopped
        if not running:
            return False
        if played:
            return True
        # A tick that came late (a command took seconds to compute) does not burst: the
        # clock catches up at most MAX_TICK_S of wall time.
        budget = math.inf if math.isinf(speed) else speed * min(dt_wall, MAX_TICK_S)
        # 1. play out frames of the last command
        if self._playout:
            self._advance_playout(budget)
            return False
        # 2. the next step, when its time comes
        step = self._next_step()
        sim_t = self.session.sim.t_s
        target = math.inf if step is None else self._start_time(step[1])
        if step is not None and sim_t + 1e-6 < self._clock_t_s and target <= self._clock_t_s:
            # the idle rover lags the clock: a due step starts at the clock shown (issue 21)
            self._idle(self._clock_t_s - sim_t)
            sim_t = self.session.sim.t_s
        if target <= sim_t + 1e-6:
            assert step is not None
            self.comm.onboard_until(sim_t)  # a cancel or a sequence that arrived meanwhile
            self._execute(step[0])
            return at_max
        if math.isinf(speed):
            # idle time is skipped: straight to the next step, or what the link brings next
            wake = min(target, self.comm.next_due_t_s())
            if wake < math.inf:
                self._idle(min(max(wake - sim_t, MIN_SKIP_S), IDLE_CHUNK_S))
                return True
            # nothing to skip to: the clock runs on in real time (IDLE_SPEED_AT_MAX)
            budget = IDLE_SPEED_AT_MAX * min(dt_wall, MAX_TICK_S)
        # a finite speed: the clock moves on; the rover is simulated in IDLE_STEP_S steps
        self._clock_t_s = min(max(self._clock_t_s, sim_t) + budget, target)
        lag = self._clock_t_s - sim_t
        if lag >= IDLE_STEP_S or self._clock_t_s >= target - 1e-6:
            self._idle(lag)
        return False

    def _next_step(self) -> tuple[QueuedSequence, TimeTag] | None:
        with self.lock:
            while self.queue:
                item = self.queue[0]
                if item.next_step < len(item.sequence.steps):
                    return item, item.sequence.steps[item.next_step].time_tag
                self.queue.popleft()
                status = "failed" if item.stopped else "completed"
                detail = "; ".join(item.problems) or None
                self._sequence_status(item.sequence_id, status, detail)
                self._queue_changed()
            return None

    def _start_time(self, tag: TimeTag) -> float:
        return start_time(tag, self.spec.mission, self.session.sim.t_s, self._last_done_t_s)

    running = property(lambda self: self._thread is not None and self._thread.is_alive())

    def idle_until(self, t_s: float) -> None:  # an uplink arrives then: nothing runs before
        self._idle(t_s - self.session.sim.t_s)

    def session_changed(self) -> None:
        """Checkpoint at the next tick: the session or link changed outside the clock thread
        (a fault, ``server.faults``; a comm change, ``server.comm``)."""
        with self.lock:
            self._clock_changed = True
        self._wake.set()

    def _idle(self, duration_s: float) -> None:
        if duration_s <= 0.0:
            return
        session = self.session
        session.execute(cmd.Wait(duration_s), label="")  # the clock's own wait: no command
        del session.reports[:]
        self._publish(self.session.take_frames())

    def _execute(self, item: QueuedSequence) -> None:
        session = self.session
        with self.lock:  # moved or cancelled since it was picked: the next tick picks again
            if not self.queue or self.queue[0] is not item:
                return
            item.started = True
            self.current_step = (item.sequence_id, item.next_step)
        step = item.sequence.steps[item.next_step]
        if item.next_step == 0 and item.wait_left_s is None:
            self._sequence_status(item.sequence_id, "running", None)
            self._queue_changed()
        command = step.command
        with self.lock:
            self.executing = command.describe()
            speed = self.clock.speed
        if isinstance(command, cmd.Wait) and not math.isinf(speed):
            # A long WAIT runs a chunk at a time (a second of wall time's worth), so the
            # play-out and the checkpoints stay small and the queue can be cancelled.
            left = command.duration_s if item.wait_left_s is None else item.wait_left_s
            chunk = min(left, max(IDLE_STEP_S, speed))
            item.wait_left_s = left - chunk
            command = cmd.Wait(chunk)
        report = session.execute(command, label=step.command.describe())
        frames = self.session.take_frames()  # they live on in the play-out, storage and hub
        with self.lock:
            self._playout.extend(frames)
            self.comm.rover_images(session.take_images())  # played out with the frames
        del session.reports[:]  # and the report in storage: the checkpoint stays small
        if item.wait_left_s is not None and item.wait_left_s > 1e-9:
            return  # more of the WAIT to come
        item.wait_left_s = None
        index = item.next_step
        self._last_done_t_s = report.end_t_s
        if report.status != "completed":
            item.problems.append(f"step {index + 1} {report.status}: {report.reason}")
        with self.lock:
            item.outcomes.append(
                StepOutcome(report.status, report.reason, report.start_t_s, report.end_t_s)
            )
            item.next_step += 1
            if report.status in ("refused", "halted"):  # the rest assumed this step: stop
                item.next_step = len(item.sequence.steps)
                item.stopped = True
        self.comm.command_reported(CommandRecord(
            item.sequence_id, index, step.command.describe(), report.status, report.reason,
            report.start_t_s, report.end_t_s, tuple(e.text for e in report.events),
        ))  # fmt: skip
        self._queue_changed()
        if report.status != "completed":
            log.info("rover %s: %s: %s", self.spec.name, report.status, report.reason)

    def _advance_playout(self, budget_s: float) -> None:
        limit = self._clock_t_s + budget_s
        out: list[PlayedFrame] = []
        with self.lock:
            while self._playout and self._playout[0][0]["t_s"] <= limit:
                out.append(self._playout.popleft())
            ended = not self._playout and self.current_step is not None
            if not self._playout:
                self.executing = ""
                self.current_step = None
        if out:
            self._emit(out)
        if ended:
            self._queue_changed()
        if not math.isinf(budget_s):  # the clock moves by the whole budget, not frame to frame
            ahead = self._playout[0][0]["t_s"] if self._playout else self.session.sim.t_s
            self._clock_t_s = max(self._clock_t_s, min(limit, ahead))

    def _publish(self, frames: list[PlayedFrame]) -> None:
        if frames:
            self._emit(frames)
        self._clock_t_s = max(self._clock_t_s, self.session.sim.t_s)

    def _emit(self, pairs: list[PlayedFrame]) -> None:
        self._clock_t_s = max(self._clock_t_s, float(pairs[-1][0]["t_s"]))
        if self.comm.rover_frames(pairs):
            return  # into the rover's store, the truth out live
        images = self.comm.due_images(float(pairs[-1][0]["t_s"]))  # stored once (by time)
        pairs = [p for p in pairs if p[0]["t_s"] > self.watermark_t_s]
        if not pairs:
            return
        batch = FrameBatch([d for d, _ in pairs], [t for _, t in pairs], images=images)
        self.last_frame, self.last_truth = pairs[-1]
        self.note_reported(e for d in batch.downlink for e in d.get("events", ()))
        self.publish(batch)

    def note_reported(self, events: Iterable[Mapping[str, Any]]) -> None:
        """Keep what the rover's ``events`` report of its onboard tables."""
        self.reported.note(events)

    def _sequence_status(self, sequence_id: int, status: str, detail: str | None) -> None:
        self.comm.sequence_status(sequence_id, status, detail, self.session.sim.t_s)

    def publish(self, batch: FrameBatch) -> None:  # to every sink, on the clock thread
        for sink in self.sinks:
            sink.publish(self.spec.name, batch)

    def checkpoint(self) -> None:
        """Checkpoint the whole state now, from the clock thread or with it stopped."""
        self._last_checkpoint_wall = time.monotonic()
        if self.listener is None:
            return
        with self.lock:
            self._clock_changed = False
            self._save(self.checkpoint_state())

    def checkpoint_state(self) -> dict[str, Any]:
        """The runtime's state as plain data (``server.storage.checkpoint``): session, queue (as
        texts), clock, play-out, step executing. The caller holds ``lock``, between commands."""
        return {
            "estimators": list(self.estimators),
            "session": self.session.state(),
            "queue": [q.state() for q in self.queue],
            "clock": asdict(self.clock),
            "last_done_t_s": self._last_done_t_s,
            "playout": [list(p) for p in self._playout],
            "clock_t_s": self._clock_t_s,
            "executing": self.executing,
            "current_step": None if self.current_step is None else list(self.current_step),
            "comm": self.comm.state(),
        }

    def _save(self, state: dict[str, Any]) -> None:
        """Encode ``state`` and hand it to the listener (the caller holds ``lock``, so
        checkpoints arrive in the order they were taken)."""
        assert self.listener is not None
        blob = encode(self.spec.name, state)
        self._last_state = state
        self.listener.checkpoint(self.spec.name, float(state["session"]["sim"]["t_s"]), blob)

    @classmethod
    def restore(cls, spec: RoverSpec, blob: bytes, listener: RuntimeListener | None = None,
                sinks: Iterable[FrameSink] = ()) -> RoverRuntime:  # fmt: skip
        """A runtime from a checkpoint blob (``server.storage.checkpoint``);
        ``CheckpointFormatError`` for one it cannot read (the caller starts the rover fresh)."""
        state = decode(spec.name, blob)
        try:
            runtime = cls(spec, estimators=tuple(state["estimators"]), listener=listener,
                          sinks=sinks)  # fmt: skip
            runtime.session.load_state(state["session"])
            runtime.queue = deque(QueuedSequence.from_state(q) for q in state["queue"])
            runtime.clock = ClockState(bool(state["clock"]["running"]), state["clock"]["speed"])
            runtime._last_done_t_s = float(state["last_done_t_s"])
            runtime._playout = deque((d, t) for d, t in state["playout"])
            runtime._clock_t_s = float(state["clock_t_s"])
            runtime.executing = str(state["executing"])
            step = state["current_step"]
            runtime.current_step = None if step is None else (int(step[0]), int(step[1]))
            runtime.comm.load_state(state.get("comm"))  # none before light time: instant
        except (KeyError, TypeError, ValueError) as exc:
            raise CheckpointFormatError(
                f"checkpoint of rover {spec.name} does not hold the state this roverops "
                f"needs ({type(exc).__name__}: {exc}); the rover starts fresh, its stored "
                "telemetry stays"
            ) from exc
        runtime._last_state = state
        return runtime


def _speed_json(speed: float) -> float | str:
    return "max" if math.isinf(speed) else speed
