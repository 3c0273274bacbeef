"""A rover runtime's communication mode (``instant`` or ``mission``) and what changes with it.

``RuntimeComm`` sits between the runtime (``server.runtime``) and everything that crosses
the link. With the link instant (the default), everything goes through at once, as before
light time was modelled: a sequence joins the rover's queue when it is accepted, reports and
telemetry reach the listener and the sinks the moment they are made, and each uplinked
sequence still gets its command history (accepted, radiated and received at once, then
started and ended on the rover's clock).

In ``mission`` mode (``roverops serve --comm mission``, or an admin's change over the API)
the runtime's link (``server.comm.mission``) carries them: the ground's queue waits for its
window, the rover's products wait in its store for a pass, and the ground learns of each
when it arrives. The truth is not the rover's to send: it goes out live, as the clock plays
it out, to the truth view.

A mode or plan change comes from a request thread and takes effect on the clock thread
(``request``, applied at its next tick and checkpointed there). Back to ``instant``,
everything on its way goes through at once (``CommLink.drain``).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable, Iterable, Mapping
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any, Literal, Protocol

from server.comm.mission import MissionLink, stage_of
from server.queue import Cancelled, QueuedSequence
from server.sinks import FrameBatch, PlayedFrame, RuntimeListener
from server.storage.records import CommandRecord
from sim.comm.link import CommLink
from sim.comm.plan import CommPlan
from sim.world.marsclock import get_mission

if TYPE_CHECKING:
    from server.rovers import RoverSpec
    from sim.loop.downlink import DownlinkDict
    from sim.loop.images import ImageDict
    from sim.scoring.truth import TruthDict

log = logging.getLogger(__name__)

CommMode = Literal["instant", "mission"]
COMM_MODES: tuple[CommMode, ...] = ("instant", "mission")
APPLY_TIMEOUT_S = 30.0  # a request waits this long for the clock thread to apply it


class CommModeError(ValueError):
    """A mode that is not one of ``COMM_MODES``."""


def check_comm_mode(mode: object) -> CommMode:
    """``mode`` if it is a communication mode, else ``CommModeError`` naming the choices."""
    if mode not in COMM_MODES:
        raise CommModeError(f"comm: must be one of {', '.join(COMM_MODES)}, got {mode!r}")
    return mode


@dataclass(frozen=True)
class CancelSent:
    """A cancel accepted by the ground, to go up in the next window (the sequence had been
    radiated): the rover reports what it found when the cancel reaches it."""

    sequence_id: int
    uplink_id: int


class Hosted(Protocol):
    """What of the runtime its comm side uses."""

    spec: RoverSpec
    lock: threading.RLock
    listener: RuntimeListener | None
    last_frame: DownlinkDict | None
    last_truth: TruthDict | None
    watermark_t_s: float

    @property
    def t_s(self) -> float: ...

    @property
    def running(self) -> bool: ...

    def take_onboard(self, entry: QueuedSequence, by_link: bool = False) -> None: ...

    def cancel_onboard(self, sequence_id: int, by_link: bool = False) -> Cancelled | None: ...

    def publish(self, batch: FrameBatch) -> None: ...

    def note_reported(self, events: Iterable[Mapping[str, Any]]) -> None: ...

    def idle_until(self, t_s: float) -> None: ...

    def session_changed(self) -> None: ...

    def amend_checkpoint(self, change: Callable[[dict[str, Any]], dict[str, Any]]) -> None: ...


class RuntimeComm:
    """The runtime's communication mode and its link (module docstring)."""

    def __init__(self, runtime: Hosted, mode: CommMode = "instant") -> None:
        self.runtime = runtime
        self.plan = CommPlan()
        self.mission: MissionLink | None = None
        self.last_received_t_s: float | None = None  # the newest downlink came down then
        self.images: list[ImageDict] = []  # images made, waiting for the clock (play-out)
        self._request: tuple[CommMode | None, CommPlan | None] | None = None
        self._applied = threading.Event()
        if check_comm_mode(mode) == "mission":
            self._start(runtime.t_s)

    @property
    def mode(self) -> CommMode:
        return "instant" if self.mission is None else "mission"

    def _start(self, t_s: float) -> None:
        site = get_mission(self.runtime.spec.mission)
        link = CommLink(site.lat_deg, site.lon_east_deg, self.plan, t_s)
        self.mission = MissionLink(link, self)

    # ---- a change of mode or plan (request threads) ------------------------------------

    def request(self, mode: CommMode | None = None, plan: CommPlan | None = None) -> None:
        """Change the mode and/or the plan: applied by the clock thread at its next tick
        (at once if it is not running) and checkpointed there; returns once applied."""
        with self.runtime.lock:
            before = self._request or (None, None)  # two requests before a tick: both apply
            self._request = (mode or before[0], plan or before[1])
            self._applied.clear()
        if not self.runtime.running:
            self.apply_request()
            return
        self.runtime.session_changed()  # wakes the clock thread, which checkpoints
        if not self._applied.wait(APPLY_TIMEOUT_S):  # a command still computing: it will
            log.warning("rover %s: comm change pending on a busy clock", self.runtime.spec.name)

    def apply_request(self) -> None:
        """Apply a pending change (the clock thread, between commands)."""
        with self.runtime.lock:
            request, self._request = self._request, None
        if request is None:
            return
        mode, plan = request
        if plan is not None:
            self.plan = plan
            if self.mission is not None:
                self.mission.link.set_plan(plan)
        if mode == "mission" and self.mission is None:
            self._start(self.runtime.t_s)
        elif mode == "instant" and self.mission is not None:
            mission = self.mission
            # what the rover answers (a receipt, a cancel's outcome) goes through as well
            while (
                (got := mission.link.drain(self.runtime.t_s)).radiated
                or got.onboard
                or (got.on_ground)
            ):
                mission.hand_on(got)
            self.mission = None
        self._applied.set()

    # ---- what crosses the link ---------------------------------------------------------

    def uplink(self, entry: QueuedSequence) -> bool:
        """Across light time, a sequence accepted by the ground waits for its window (True);
        with the link instant it goes onboard at once (False: the caller queues it)."""
        t_s = self.runtime.t_s
        self.stage(entry.sequence_id, "accepted", t_s)
        if self.mission is None:
            for stage in ("radiated", "received"):
                self.stage(entry.sequence_id, stage, t_s)
            return False
        with self.runtime.lock:
            uplink = self.mission.uplink_sequence(entry, t_s)
            self._amend_waiting(lambda waiting: [*waiting, asdict(uplink)], uplink.id)
        self.stage(entry.sequence_id, "waiting", t_s)
        return True

    def _amend_waiting(
        self, change: Callable[[list[dict[str, Any]]], list[dict[str, Any]]], next_id: int
    ) -> None:
        """A change of the ground's uplink queue stored at once: applied to the last
        checkpoint's (the clock thread may be mid-command, so the link's state now is not
        the checkpoint's), as the runtime does a queue change (caller holds the lock)."""

        def amended(last: dict[str, Any]) -> dict[str, Any]:
            comm = last.get("comm") or {}
            mission = comm.get("mission")
            if mission is None:  # checkpointed before the mode changed: the tick stores it
                return {}
            link = {
                **mission["link"],
                "waiting": change(mission["link"]["waiting"]),
                "next_uplink_id": max(int(mission["link"]["next_uplink_id"]), next_id + 1),
            }
            return {"comm": {**comm, "mission": {**mission, "link": link}}}

        self.runtime.amend_checkpoint(amended)

    def cancel(self, sequence_id: int) -> Cancelled | CancelSent | None:
        """Across light time: a sequence still on the ground is dropped there (``Cancelled``);
        one radiated gets a cancel that goes up (``CancelSent``); ``None`` for one the ground
        holds neither way."""
        assert self.mission is not None
        with self.runtime.lock:
            waiting = next(
                (
                    u
                    for u in self.mission.link.waiting
                    if u.kind == "sequence" and u.sequence_id == sequence_id
                ),
                None,
            )
            if waiting is not None:
                self.mission.withdraw(sequence_id)
                self._amend_waiting(
                    lambda ws: [w for w in ws if int(w["id"]) != waiting.id], waiting.id
                )
                steps = len(QueuedSequence.from_state(waiting.payload).sequence.steps)
                return Cancelled(steps=steps, done=0, running_step=None)
            if sequence_id not in self.mission.radiated_ids:
                return None
            uplink = self.mission.uplink_cancel(sequence_id, self.runtime.t_s)
            self._amend_waiting(lambda ws: [*ws, asdict(uplink)], uplink.id)
        self.stage(sequence_id, "cancel accepted", self.runtime.t_s)
        return CancelSent(sequence_id, uplink.id)

    def held_ids(self) -> list[int]:
        """The sequences the link holds: on the ground, on their way, onboard unreported."""
        if self.mission is None:
            return []
        with self.runtime.lock:
            rising = [u.sequence_id for u in self.mission.link.rising if u.kind == "sequence"]
            return [*self.mission.waiting_ids(), *rising, *sorted(self.mission.radiated_ids)]

    def rover_images(self, images: list[ImageDict]) -> None:
        """Images a command made: they are played out with the first frames at or after
        them (``due_images``), as the telemetry is (the caller holds the runtime's lock)."""
        self.images.extend(images)

    def due_images(self, t_s: float) -> list[ImageDict]:
        """The images made by ``t_s``, taken for the batch played out to then."""
        with self.runtime.lock:
            due = [i for i in self.images if i["t_s"] <= t_s]
            self.images = [i for i in self.images if i["t_s"] > t_s]
        return due

    def rover_frames(self, pairs: list[PlayedFrame]) -> bool:
        """Across light time, played-out frames: the downlink (and the images made by its
        last frame) into the rover's store, the truth out live (True); with the link
        instant, False (the runtime publishes them, with ``due_images``)."""
        if self.mission is None:
            return False
        runtime = self.runtime
        live = [t for _, t in pairs if t["t_s"] > runtime.watermark_t_s]  # not stored yet
        if live:
            runtime.last_truth = live[-1]
            runtime.publish(FrameBatch([], live))
        images = self.due_images(pairs[-1][0]["t_s"])
        with runtime.lock:
            self.mission.rover_frames([d for d, _ in pairs], images)
        return True

    def command_reported(self, record: CommandRecord) -> None:
        """A step's report: to the listener, or across light time into the rover's store."""
        if self.mission is None:
            if self.runtime.listener is not None:
                self.runtime.listener.command_reported(self.runtime.spec.name, record)
            return
        report = {"type": "command", **asdict(record), "events": list(record.events)}
        with self.runtime.lock:
            self.mission.rover_report(record.end_t_s, report)

    def sequence_status(
        self, sequence_id: int, status: str, detail: str | None, t_s: float
    ) -> None:
        """A sequence started or ended on the rover's clock ``t_s`` (as ``command_reported``)."""
        if self.mission is None:
            self.status_arrived(sequence_id, status, detail)
            self.stage(sequence_id, stage_of(status, detail), t_s, detail)
            return
        report = {
            "type": "sequence",
            "sequence_id": sequence_id,
            "status": status,
            "detail": detail,
        }
        with self.runtime.lock:
            self.mission.rover_report(t_s, report)

    def ground_state(self) -> dict[str, Any]:
        """Across light time, what the rover's ``/state`` says of its queue and the command
        it runs: what the ground knows (the sequences it holds or has radiated, the command
        the newest downlink reports), never the rover's own queue; nothing with the link
        instant."""
        mission = self.mission
        if mission is None:
            return {}
        with self.runtime.lock:
            ups = [*mission.link.waiting, *mission.link.rising]
        queue = [
            QueuedSequence.from_state(u.payload).summary() for u in ups if u.kind == "sequence"
        ]
        frame = self.runtime.last_frame
        return {"queue": queue, "executing": "" if frame is None else frame.get("command", "")}

    # ---- the clock ----------------------------------------------------------------------

    def advance(self, t_s: float) -> None:
        if self.mission is not None:
            self.mission.advance(t_s)

    def onboard_until(self, t_s: float) -> None:
        """Before the rover starts a step at ``t_s``: what has reached it by then."""
        if self.mission is not None:
            self.mission.onboard_until(t_s)

    def next_due_t_s(self) -> float:
        """When the link next brings something the operators wait for: while a sequence is
        on the ground, on its way or onboard unreported (``inf`` otherwise, and with the link
        instant: at max speed the idle clock then runs in real time, as without light time)."""
        mission = self.mission
        if mission is None:
            return math.inf
        with self.runtime.lock:
            link = mission.link
            if not (link.waiting or link.rising or mission.radiated_ids):
                return math.inf
            return link.next_due_t_s()

    # ---- the link's host (server.comm.mission.LinkHost) ----------------------------------

    def take_uplink(self, entry: QueuedSequence, arrival_t_s: float) -> None:
        self.runtime.idle_until(arrival_t_s)  # nothing runs before it is onboard
        self.runtime.take_onboard(entry, by_link=True)

    def cancel_onboard(self, sequence_id: int) -> dict[str, Any]:
        stopped = self.runtime.cancel_onboard(sequence_id, by_link=True)
        if stopped is None:
            return {"found": False}
        return {"found": True, "where": stopped.where()}

    def downlink_arrived(self, batch: FrameBatch, recovering: bool) -> None:
        runtime = self.runtime
        if recovering and runtime.listener is not None:
            stored = runtime.listener.stored_frame_times(runtime.spec.name, batch.downlink)
            fresh = [d for d in batch.downlink if d["t_s"] not in stored]
            if not fresh and not batch.images:  # images stored already are not stored again
                return
            batch = FrameBatch(fresh, [], batch.received_t_s, batch.images)
        newest = max(batch.downlink, key=lambda d: d["t_s"], default=None)  # a pass of images
        if newest is not None and (
            runtime.last_frame is None or newest["t_s"] > runtime.last_frame["t_s"]
        ):
            runtime.last_frame = newest
            self.last_received_t_s = batch.received_t_s
        runtime.note_reported(e for d in batch.downlink for e in d.get("events", ()))
        runtime.publish(batch)

    def command_arrived(self, report: Mapping[str, Any]) -> None:
        fields = {k: v for k, v in report.items() if k != "type"}
        record = CommandRecord(**{**fields, "events": tuple(fields.get("events", ()))})
        if (listener := self.runtime.listener) is not None:
            listener.command_reported(self.runtime.spec.name, record)
            listener.queue_changed(self.runtime.spec.name)  # the onboard side, as reported

    def status_arrived(self, sequence_id: int, status: str, detail: str | None,
                       t_s: float | None = None) -> None:  # fmt: skip
        if self.runtime.listener is not None:
            self.runtime.listener.sequence_status(sequence_id, status, detail, t_s)

    def stage(self, sequence_id: int, stage: str, t_s: float, detail: str | None = None) -> None:
        if (listener := self.runtime.listener) is not None:
            listener.sequence_stage(sequence_id, stage, t_s, detail)
            listener.queue_changed(self.runtime.spec.name)  # a stage moves it on the queue

    def event(
        self, t_s: float, event: dict[str, str], recovering: bool, received_t_s: float
    ) -> None:
        if self.runtime.listener is not None:
            self.runtime.listener.link_event(
                self.runtime.spec.name, t_s, event, recovering, received_t_s
            )

    # ---- checkpoint -------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        return {
            "plan": self.plan.as_json(),
            "mission": None if self.mission is None else self.mission.state(),
            "last_received_t_s": self.last_received_t_s,
            "images": list(self.images),
        }

    def load_state(self, state: Mapping[str, Any] | None) -> None:
        """From ``state()``; ``None`` (a checkpoint from before light time): instant."""
        if state is None:
            return
        self.plan = CommPlan.from_json(state["plan"])
        self.last_received_t_s = state["last_received_t_s"]
        self.images = list(state.get("images", []))  # none before images came down
        self.mission = None
        if state["mission"] is not None:
            self._start(self.runtime.t_s)
            assert self.mission is not None
            self.mission.load_state(state["mission"])
