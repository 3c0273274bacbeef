"""The server's state: its settings (``ServerConfig``) and ``Server``, which owns the rover
runtimes, storage, the accounts, the audit log, the alarm engine, the WebSocket hub and the
3D views, and wires a frame's route through them.

A frame's route: each ``RoverRuntime`` (``server.runtime``) plays its frames out as its
clock reaches them and hands every batch, in order, to its named sinks (``server.sinks``):
``StorageSink`` (frames and their events, through the ``BatchWriter``), the
``AlarmEngine`` (limits judged, alarms raised and cleared), the ``TelemetryHub`` (the
console's WebSocket) and, with the 3D view on, the rover's ``RoverScene``. The routes
(``server.api``) read this state through ``server.api.deps.ServerDep``.
"""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass
from typing import Any

from sequences.validate import ValidationContext, validate
from server.access.accounts import Accounts
from server.access.audit import AuditEntry, AuditLog
from server.access.truth_view import check_truth_view
from server.alarms import AlarmEngine
from server.comm.hosting import check_comm_mode
from server.errors import UnknownRoverError
from server.hub import TelemetryHub
from server.notices import CommandNotice, EventNotice, QueueNotice
from server.queue_view import QueueNotices, queue_json
from server.runtime import ROVERS, CheckpointFormatError, RoverRuntime
from server.scene3d.scene import RoverScene
from server.sinks import FrameSink, StorageSink
from server.storage import BatchWriter, CommandRecord, Store
from server.timeline import stored_command
from server.validation.context import rover_site, validation_context
from server.validation.pool import ValidationPool
from server.validation.uploads import ValidationSlots
from sim.loop.downlink import DownlinkDict
from sim.world.marsclock import t_s_to_utc

log = logging.getLogger(__name__)

MAX_UPLOAD_BYTES = 1_000_000
MAX_CONCURRENT_VALIDATIONS = 2  # per client address, and per token
VALIDATION_PROCESSES = 1  # one core of two for uploads, the other for the server


@dataclass
class ServerConfig:
    """Settings of one server (``roverops serve`` fills them from flags and ROVEROPS_*)."""

    database_url: str
    # the bootstrap admin token (--operator-token): in memory only, for scripts and tests;
    # None: only the users' tokens in the database are accepted
    operator_token: str | None = None
    # reading (telemetry, sequences, timelines, the 3D view) needs no token while on
    public_read: bool = True
    # who sees the simulator's truth (server.access.truth_view): everyone, or conductor
    # (the conductor role and above; everyone else gets the rover's downlink alone)
    truth_view: str = "everyone"
    max_upload_bytes: int = MAX_UPLOAD_BYTES  # every request body, uploads or not
    max_concurrent_validations: int = MAX_CONCURRENT_VALIDATIONS
    # uploads validate in these worker processes (server.validation.pool); 0: in the
    # server's threadpool, sharing its interpreter lock (slower answers while one runs)
    validation_processes: int = VALIDATION_PROCESSES
    start_clocks: bool = True
    initial_speed: float = 1.0
    viewer_3d: bool = False  # a viser 3D view per rover under /viser/{rover}/
    # what runs beside SAPP on a new rover (sim.loop.side.kinematic); a rover restored from a
    # checkpoint keeps the estimators it was started with
    estimators: tuple[str, ...] = ("sapp",)
    # the link of a new rover (server.comm): instant, or mission (across light time); a
    # rover restored from a checkpoint keeps its own
    comm: str = "instant"
    # rehearsal campaigns (server.rehearsal.service): a running Dask scheduler's
    # tcp://host:port; None: an embedded cluster started on the first campaign
    dask_scheduler: str | None = None

    def __post_init__(self) -> None:
        self.truth_view = check_truth_view(self.truth_view)
        self.comm = check_comm_mode(self.comm)


@dataclass(frozen=True)
class ServerParts:
    """What a ``Server`` is built from, made before it: its storage and the services over
    it. ``ServerParts.open(config)`` makes the ones a configuration asks for; a test may
    build its own (an in-memory store, a pool with no worker processes)."""

    store: Store
    accounts: Accounts
    audit: AuditLog
    writer: BatchWriter  # the frames, events, commands and checkpoints, off the clock threads
    hub: TelemetryHub
    validation: ValidationPool
    slots: ValidationSlots  # a client's validations at once (429 past them)

    @classmethod
    def open(cls, config: ServerConfig) -> ServerParts:
        store = Store(config.database_url)
        return cls(
            store=store,
            accounts=Accounts(store, config.operator_token),
            audit=AuditLog(store),
            writer=BatchWriter(store),
            hub=TelemetryHub(),
            validation=ValidationPool(config.validation_processes),
            slots=ValidationSlots(config.max_concurrent_validations),
        )


class Server:
    """The app's state: the runtimes, storage, the writer, the hub and the frame sinks
    (module docstring). It is each runtime's listener (``server.sinks.RuntimeListener``):
    it stores and announces what the runtimes report beside their frames."""

    def __init__(self, config: ServerConfig, parts: ServerParts) -> None:
        self.config = config
        self.store = parts.store
        self.accounts = parts.accounts
        self.audit = parts.audit
        self.writer = parts.writer
        self.hub = parts.hub
        self.validation = parts.validation
        self.slots = parts.slots
        self.rovers: dict[str, RoverRuntime] = {}
        self.queue_notices = QueueNotices(
            self._queue_notice, self.hub.notify, lambda rover: self.hub.count(rover) > 0
        )
        self.alarms = AlarmEngine(self.store, self._when, self.hub.notify)
        self.alarms.on_event = self._server_event
        # every played-out batch, in order: stored, judged against the limits, sent live
        # (and drawn in the 3D view, below: a RoverScene is the sink of its own rover)
        self.sinks: list[FrameSink] = [StorageSink(self.writer), self.alarms, self.hub]
        refused: dict[str, str] = {}  # rover -> why its checkpoint was refused
        self.resumed: set[str] = set()  # rovers this start found a checkpoint of
        for name, spec in ROVERS.items():
            saved = self.store.load_checkpoint(name)
            try:
                runtime = RoverRuntime.restore(spec, saved[1], self, self.sinks) if saved else None
            except CheckpointFormatError as error:  # an older format: the rover starts fresh
                log.warning("%s", error)
                refused[name] = str(error)
                saved = None
            if saved is None:
                runtime = RoverRuntime(
                    spec,
                    estimators=config.estimators,
                    listener=self,
                    sinks=self.sinks,
                    comm=check_comm_mode(config.comm),
                )
            assert runtime is not None
            if saved is None:
                runtime.set_clock(speed=config.initial_speed)
            if saved is not None:
                self.resumed.add(name)
                self._resume(runtime)
            self.rovers[name] = runtime
        for name, why in refused.items():
            self._drop_stale_queue(name, why)
        # the 3D views: a scene joins its rover's sinks when it starts (RoverScene.start).
        # With the truth for everyone, one scene per rover; with --truth-view conductor, a
        # scene of the downlink alone for everyone and one with the truth for the truth view
        # (viser sends a scene's nodes to all its clients: server.scene3d.scene).
        self.scenes: dict[str, RoverScene] = {}
        self.truth_scenes: dict[str, RoverScene] = {}
        if config.viewer_3d:
            everyone = config.truth_view == "everyone"
            self.scenes = {
                name: RoverScene(rt, self.store, truth=everyone) for name, rt in self.rovers.items()
            }
            if not everyone:
                self.truth_scenes = {
                    name: RoverScene(rt, self.store, truth=True) for name, rt in self.rovers.items()
                }

    @classmethod
    def open(cls, config: ServerConfig) -> Server:
        """A server over the parts ``config`` asks for (``ServerParts.open``)."""
        return cls(config, ServerParts.open(config))

    def _resume(self, runtime: RoverRuntime) -> None:
        """After a restart: no frame stored twice, and every accepted sequence the
        checkpoint does not hold (accepted or started after it) queued again, in order, an
        immediate command (format ``command``) first as when it was sent."""
        rover = runtime.spec.name
        last = self.store.last_frame(rover)
        truth = self.store.last_truth(rover)
        if last is not None or truth is not None:
            # the truth is stored as it is played out, the downlink (across light time) when
            # it reaches the ground: the truth's time is how far play-out had got
            runtime.watermark_t_s = max(float(r["t_s"]) for r in (last, truth) if r is not None)
            runtime.last_frame = last
            runtime.last_truth = truth
            runtime.note_reported(self.store.events(rover, -math.inf, math.inf))
        if runtime.comm.mission is not None:
            runtime.comm.mission.received_until_t_s = self.store.received_until(rover)
        held = set(runtime.queued_ids())
        pending = [
            s
            for s in self.store.list_sequences(rover)
            if s["status"] in ("queued", "running") and s["id"] not in held
        ]
        for summary in sorted(pending, key=lambda s: s["id"]):
            stored = self.store.get_sequence(summary["id"])
            assert stored is not None
            text = stored["source"]
            source = json.loads(text) if stored["format"] in ("json", "command") else text
            result = validate(source)
            if result.sequence is None:  # cannot happen: it was accepted
                self.store.set_sequence_status(summary["id"], "failed", "unreadable after restart")
                continue
            runtime.enqueue(summary["id"], result.sequence, stored["format"] == "command")

    def _when(self, rover: str, t_s: float) -> dict[str, Any]:
        runtime = self.rovers[rover]
        return {"t_s": t_s, "utc": t_s_to_utc(t_s).isoformat(), "lmst_h": runtime.lmst_h(t_s),
                "sol": runtime.sol(t_s)}  # fmt: skip

    # ---- the runtimes' listener (server.sinks.RuntimeListener) -------------------------

    def command_reported(self, rover: str, report: CommandRecord) -> None:
        self.writer.command(rover, report)
        if self.hub.count(rover):  # a live timeline shows it: read back (so written) as listed
            entry = stored_command(self.store, self.rovers[rover], report)
            if entry is not None:
                self.hub.notify(rover, CommandNotice(entry))

    def sequence_status(
        self, sequence_id: int, status: str, detail: str | None, t_s: float | None = None
    ) -> None:
        self.writer.flush()
        before = self.store.get_sequence(sequence_id)
        self.store.set_sequence_status(sequence_id, status, detail)
        if before is None:
            return
        said = {"running": "started", "completed": "completed", "failed": "failed"}
        severity = "error" if status == "failed" else "warning" if detail else "info"
        text = f"sequence #{sequence_id} {before['name']} {said.get(status, status)}"
        text += f": {detail}" if detail else ""
        rover = before["rover"]
        # the same status again (resumed after a restart): its event only if a kill lost it
        if before["status"] == status and any(
            e["text"] == text
            for e in self.store.event_log(
                rover, -math.inf, math.inf, kinds=("sequence",), text_contains=text
            )[0]
        ):
            return
        self._server_event(rover, t_s, {"text": text, "kind": "sequence", "severity": severity})
        self.writer.flush()  # with the status it tells of: a kill now loses neither

    def sequence_stage(
        self, sequence_id: int, stage: str, t_s: float, detail: str | None = None
    ) -> None:
        try:
            self.store.add_stage(sequence_id, stage, t_s, detail)
        except KeyError:  # a sequence of a test's own, never stored
            log.warning("stage %s of unknown sequence #%s", stage, sequence_id)

    def link_event(
        self, rover: str, t_s: float, event: dict[str, str], recovering: bool,
        received_t_s: float | None = None,
    ) -> None:  # fmt: skip
        if recovering and any(
            e["text"] == event["text"] for e in self.store.events(rover, t_s, t_s)
        ):
            return  # stored before the restart
        self._server_event(rover, t_s, event, received_t_s)

    def stored_frame_times(self, rover: str, downlinks: list[DownlinkDict]) -> set[float]:
        return self.store.stored_frame_times(rover, (float(d["t_s"]) for d in downlinks))

    def checkpoint(self, rover: str, t_s: float, blob: bytes) -> None:
        self.writer.checkpoint(rover, t_s, blob)

    def commit(self) -> None:
        self.writer.flush()  # a clock or queue change is stored before it is answered

    def queue_changed(self, rover: str) -> None:
        self.queue_notices.changed(rover)

    # ---- the server's own events -------------------------------------------------------

    def _drop_stale_queue(self, rover: str, why: str) -> None:
        """A rover that started fresh has an empty queue: the sequences its refused
        checkpoint held (queued or running) are cancelled, not left "queued" for ever, and
        the event log says why."""
        stale = [
            s for s in self.store.list_sequences(rover) if s["status"] in ("queued", "running")
        ]
        for s in stale:
            self.store.set_sequence_status(s["id"], "cancelled", why)
        names = ", ".join(f"#{s['id']} {s['name']}" for s in reversed(stale))
        self._server_event(rover, None, {
            "text": why + (f"; cancelled: {names}" if names else ""),
            "kind": "sequence", "severity": "warning"})  # fmt: skip

    def _server_event(
        self, rover: str, t_s: float | None, event: dict[str, str],
        received_t_s: float | None = None,
    ) -> None:  # fmt: skip
        """An event the server makes (``estimation.events``: kinds ``sequence``, ``alarm``),
        at ``t_s`` or the rover's clock now: stored for the event log and sent as an
        ``event`` notice (it is in no frame); ``received_t_s``: a link's, as it came down."""
        t = self.rovers[rover].t_s if t_s is None else t_s
        when = self._when(rover, t)
        self.writer.events(rover, [(t, event)], received_t_s)
        self.hub.notify(rover, EventNotice(
            {**event, "t_s": t, "sol": when["sol"], "lmst_h": when["lmst_h"]}))  # fmt: skip

    def _queue_notice(self, rover: str) -> QueueNotice:
        return QueueNotice(rover, queue_json(self.rovers[rover], self.store))

    def _record_start(self) -> None:
        """The server's own start on every rover's event log, at the rover's clock now, and
        in the audit log: after a crash or a stop the console's operators see when the
        server came back (and the timeline marks it), not only that the readouts move again.
        A rover found with a checkpoint is a restart (one refused for its format too)."""
        for name in self.rovers:
            if name in self.resumed:
                text, severity = (
                    "server restarted: the rover resumed from its last checkpoint",
                    "warning",
                )
            else:
                text, severity = "server started", "info"
            self._server_event(name, None, {"text": text, "kind": "server", "severity": severity})
        action = "server restarted" if self.resumed else "server started"
        self.audit.add(AuditEntry(username="server", method="START", path="roverops serve",
                                  status=200, action=action))  # fmt: skip

    def start(self) -> None:
        self.writer.start()
        self._record_start()
        self.queue_notices.start()
        self.validation.start(rover_site(next(iter(self.rovers.values()))))
        for scene in [*self.scenes.values(), *self.truth_scenes.values()]:
            scene.start()
        if self.config.start_clocks:
            for runtime in self.rovers.values():
                runtime.start()

    def stop(self) -> None:
        """Each rover's clock stopped and checkpointed where it stopped, then everything
        written: a graceful stop (SIGTERM) loses nothing."""
        for runtime in self.rovers.values():
            runtime.stop()
        self.queue_notices.stop()
        for scene in [*self.scenes.values(), *self.truth_scenes.values()]:
            scene.stop()
        self.validation.stop()
        self.writer.stop()
        self.store.close()

    def rover(self, name: str) -> RoverRuntime:
        """The runtime of rover ``name`` (``UnknownRoverError`` if this server runs none)."""
        if name not in self.rovers:
            raise UnknownRoverError(name, list(self.rovers))
        return self.rovers[name]

    def scene_for(self, rover: str, sees_truth: bool) -> RoverScene | None:
        """The 3D view of ``rover`` for a viewer who sees the truth or not, ``None`` when
        the 3D view is off."""
        if sees_truth and rover in self.truth_scenes:
            return self.truth_scenes[rover]
        return self.scenes.get(rover)

    def context(self, runtime: RoverRuntime) -> ValidationContext:
        """What validation warnings need to know of a rover, from its state now."""
        return validation_context(runtime)
