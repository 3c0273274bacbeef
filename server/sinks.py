"""Where a rover's telemetry and reports go: the frame sinks and the runtime's listener.

A ``RoverRuntime`` plays its frames out as its clock reaches them and hands each batch, in
order, to every sink in its ``sinks`` list: storage (the records, their events and the
images that came with them), the alarm
engine, the WebSocket hub and the 3D view. A batch (``FrameBatch``) is two lists of the same
length: the rover's downlink records (``sim.loop.downlink.DownlinkDict``, what
``Downlink.as_dict()`` gives) and, at the same times, the scorer's truth records
(``sim.scoring.truth.TruthDict``). The records are typed dicts, not the dataclasses: every
sink sends or stores them as JSON, so each is made once, when it is played out. A sink that
serves the ground reads the downlink; the truth goes only where the truth view allows it
(docs/DESIGN.md, "Two records").

``server.state.Server`` wires them: every runtime gets ``StorageSink``, the alarm engine
(``server.alarms.AlarmEngine``) and the hub (``server.hub.TelemetryHub``), in that order,
and a 3D view (``server.scene3d.scene.RoverScene``) joins its rover's sinks when it starts.

What a runtime reports beside its frames (a command's report, a sequence's status, a
checkpoint, a queue change) goes to the one ``RuntimeListener`` it is built with: the
``Server``, which stores and announces it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, cast

from sim.loop.downlink import DownlinkDict
from sim.loop.images import ImageDict
from sim.scoring.truth import TruthDict, merged

if TYPE_CHECKING:
    from server.storage.records import CommandRecord

Frame = dict[str, Any]  # a merged frame (downlink and truth) as a JSON-ready dict
PlayedFrame = tuple[DownlinkDict, TruthDict]  # a downlink record and its truth record


@dataclass(frozen=True)
class FrameBatch:
    """Records handed on together. With the link instant (``server.comm``), a batch is
    played out whole: ``downlink[i]`` and ``truth[i]`` share their ``t_s``. Across light
    time the two records part: the truth goes out live as the clock plays it out (a batch
    of truth records alone), the downlink when it reaches the ground (a batch of downlink
    records alone, ``received_t_s`` when it arrived; older data may come after newer, as
    a pass fills in the telemetry it sent decimated first). ``images``: the image products
    (``sim.loop.images``) that came with the downlink (played out with the frames after
    them, or down in the same pass); never with a batch of truth alone."""

    downlink: list[DownlinkDict]
    truth: list[TruthDict]
    received_t_s: float | None = None  # on the ground then (None: as it was made)
    images: list[ImageDict] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.downlink and self.truth and len(self.downlink) != len(self.truth):
            raise ValueError(
                f"a batch pairs its records: {len(self.downlink)} downlink, {len(self.truth)} truth"
            )

    @property
    def paired(self) -> bool:
        """Both records of each frame, played out together (the instant link)."""
        return len(self.downlink) == len(self.truth)

    def pairs(self) -> list[tuple[DownlinkDict | None, TruthDict | None]]:
        """Each frame's records, ``None`` for the one the batch does not carry."""
        if self.paired:
            return list(zip(self.downlink, self.truth, strict=True))
        if self.downlink:
            return [(d, None) for d in self.downlink]
        return [(None, t) for t in self.truth]

    def __len__(self) -> int:
        return max(len(self.downlink), len(self.truth))


def with_truth(downlink: DownlinkDict | None, truth: TruthDict | None) -> Frame | None:
    """``downlink`` merged with its ``truth`` record (``sim.scoring.truth.merged``); across
    light time, with the newest truth of another time (``live_frame``); with no truth,
    ``downlink`` as it is."""
    if downlink is None:
        return None
    if truth is None:
        return dict(downlink)
    if truth["t_s"] != downlink["t_s"]:
        return live_frame(downlink, truth)
    return merged(downlink, truth)


def live_frame(downlink: Mapping[str, Any], truth: TruthDict | None) -> dict[str, Any]:
    """Across light time, the truth view's frame: the newest downlink on the ground with the
    newest truth record (live) merged in, ``truth_t_s`` the truth's own time; the truth's
    events are left out (they are stored with it, and would be stamped with the
    downlink's time here)."""
    if truth is None:
        return dict(downlink)
    live = cast("TruthDict", {**truth, "t_s": downlink["t_s"], "events": []})
    return {**merged(cast("DownlinkDict", downlink), live), "truth_t_s": truth["t_s"]}


class FrameSink(Protocol):
    """Receives every frame batch of the rovers it is attached to, in play-out order, on the
    rover's clock thread: it must not block (queue the work if it is slow)."""

    def publish(self, rover: str, batch: FrameBatch) -> None: ...


class RuntimeListener(Protocol):
    """What a rover runtime reports beside its frames, given to it when it is built. Called
    on the runtime's clock thread (``checkpoint`` under its lock, so checkpoints arrive in
    the order they were taken), or on the thread that changed the queue or the clock."""

    def command_reported(self, rover: str, report: CommandRecord) -> None:
        """A queued step ended (completed, refused or failed)."""

    def sequence_status(
        self, sequence_id: int, status: str, detail: str | None, t_s: float | None = None
    ) -> None:
        """A sequence started, completed or failed (at the rover's ``t_s``; ``None``: now)."""

    def checkpoint(self, rover: str, t_s: float, blob: bytes) -> None:
        """The runtime's encoded state at ``t_s``, to be stored (queued, not waited for)."""

    def commit(self) -> None:
        """Store what ``checkpoint`` queued, now: a clock or queue change is stored before
        the request that made it is answered."""

    def queue_changed(self, rover: str) -> None:
        """The queue or the step executing changed (it must not wait)."""

    def sequence_stage(
        self, sequence_id: int, stage: str, t_s: float, detail: str | None = None
    ) -> None:
        """A stage of an uplinked sequence (its command history, ``server.comm``) at ``t_s``,
        as the ground knows it now; a stage recorded already is not recorded again."""

    def link_event(
        self, rover: str, t_s: float, event: dict[str, str], recovering: bool,
        received_t_s: float | None = None,
    ) -> None:  # fmt: skip
        """An event of the link the ground learns (a gap, a cancel's outcome) at
        ``received_t_s``; with ``recovering`` it may be stored already (delivered again
        after a restart)."""

    def stored_frame_times(self, rover: str, downlinks: list[DownlinkDict]) -> set[float]:
        """Which of ``downlinks`` (their ``t_s``) storage holds already."""
        return set()


class StorageSink:
    """Both records of every frame and the events they carry, handed to the storage writer
    (it batches them into transactions off the clock thread)."""

    def __init__(self, writer: Any) -> None:  # server.storage.BatchWriter
        self.writer = writer

    def publish(self, rover: str, batch: FrameBatch) -> None:
        events = [(float(f["t_s"]), e) for f in batch.downlink for e in f.get("events", [])]
        # one call: a flush never parts a frame from its events
        self.writer.frames(rover, batch.downlink, batch.truth, events, batch.received_t_s)
        if batch.images:  # stored once, as PNG, off the clock thread (server.storage.images)
            self.writer.images(rover, batch.images, batch.received_t_s)
