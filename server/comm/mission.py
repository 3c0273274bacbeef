"""A rover's link across light time as its runtime hosts it (``roverops serve --comm
mission``): the simulator's link (``sim.comm.link``) between the ground's queue and the
rover's, and the products that come down turned into what the ground stores and shows.

The runtime hands the link what the ground radiates (``uplink_sequence``, ``uplink_cancel``)
and what the rover makes (``rover_frames``, ``rover_report``), and advances it with its clock
(``advance``). What the link brings about goes back through the runtime (``LinkHost``):

- an uplink radiated: its ``radiated`` stage (the ground knows it at once);
- an uplink onboard: a sequence joins the rover's queue, a cancel cancels there; the rover
  acknowledges either with a report that comes down like any product (``received``, and the
  cancel's outcome: where the sequence stopped, or that it had ended before);
- products on the ground: the telemetry (``FrameBatch`` of downlink records, stamped with
  their arrival), command reports, sequence status and stages at the rover's own times, the
  gaps the store reports, and the store's own account at each pass.

The ground's bookkeeping (the store as last reported, what each pass brought) is kept here,
in the checkpoint with the link. After a restart the runtime resumes from its checkpoint and
delivers again what had reached the ground after it. Storage holds nothing received after
``received_until_t_s`` (the latest arrival it holds), so only what arrives up to then is
handed on ``recovering``: the host stores of it only what storage does not hold yet.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

from sequences.language import to_text
from server.queue import QueuedSequence
from server.sinks import FrameBatch
from sim.comm.link import SEARCH_SOLS, CommLink, Progress, Sent, Uplink
from sim.comm.plan import CommPlan
from sim.comm.store import HEADER_BITS
from sim.loop.downlink import DownlinkDict
from sim.loop.images import ImageDict, as_image, image_bits

PASSES_KEPT = 64  # the passes the ground remembers what it received from


class LinkHost(Protocol):
    """What the runtime does for its link (module docstring). ``recovering``: what is
    handed on may be stored already (delivered again after a restart)."""

    def take_uplink(self, entry: QueuedSequence, arrival_t_s: float) -> None:
        """A sequence reached the rover: into its queue."""

    def cancel_onboard(self, sequence_id: int) -> dict[str, Any]:
        """A cancel reached the rover: cancel there; what it found, for its report."""

    def downlink_arrived(self, batch: FrameBatch, recovering: bool) -> None:
        """Telemetry reached the ground."""

    def command_arrived(self, report: Mapping[str, Any]) -> None:
        """A command's report reached the ground (a ``CommandRecord``'s fields)."""

    def status_arrived(self, sequence_id: int, status: str, detail: str | None,
                       t_s: float | None = None) -> None:  # fmt: skip
        """A sequence's status (at the rover's ``t_s``) reached the ground."""

    def stage(self, sequence_id: int, stage: str, t_s: float, detail: str | None = None) -> None:
        """A stage of an uplinked sequence the ground knows of now (at ``t_s``)."""

    def event(
        self, t_s: float, event: dict[str, str], recovering: bool, received_t_s: float
    ) -> None:
        """An event of the link the ground learns (a gap, a cancel's outcome)."""


class MissionLink:
    """The link of one rover and the ground's account of it (module docstring)."""

    def __init__(self, link: CommLink, host: LinkHost) -> None:
        self.link = link
        self.host = host
        self.received_until_t_s = -math.inf  # stored already (after a restart)
        self.store_reported: dict[str, Any] | None = None  # the store's last account
        self.passes: dict[str, dict[str, Any]] = {}  # pass start -> what came down of it
        self.gaps: list[dict[str, Any]] = []  # the store's drops, as reported
        self.radiated_ids: set[int] = set()  # sequences radiated, not known to have ended

    @property
    def plan(self) -> CommPlan:
        return self.link.plan

    # ---- in --------------------------------------------------------------------------

    def uplink_sequence(self, entry: QueuedSequence, t_s: float) -> Uplink:
        """The ground radiates a sequence at its next window."""
        bits = HEADER_BITS + 8 * len(to_text(entry.sequence).encode("utf-8"))
        return self.link.accept("sequence", entry.sequence_id, bits, t_s, entry.state())

    def uplink_cancel(self, sequence_id: int, t_s: float) -> Uplink:
        """The ground radiates a cancel of an uplinked sequence at its next window."""
        return self.link.accept("cancel", sequence_id, HEADER_BITS + 32, t_s)

    def withdraw(self, sequence_id: int) -> bool:
        """Take back a sequence still on the ground (not radiated)."""
        return self.link.withdraw(sequence_id) is not None

    def waiting_ids(self) -> list[int]:
        """The sequences on the ground, waiting for a window, in order."""
        return [u.sequence_id for u in self.link.waiting if u.kind == "sequence"]

    def rover_frames(self, downlinks: list[DownlinkDict], images: Sequence[ImageDict] = ()) -> None:
        """Into the store in the rover's time order, the images among the frames."""
        store, waiting = self.link.store, sorted(images, key=lambda i: i["t_s"])
        for frame in downlinks:
            while waiting and waiting[0]["t_s"] <= frame["t_s"]:
                image = waiting.pop(0)
                store.add_image(image, image_bits(image["width_px"], image["height_px"]))
            store.add_frame(frame)
        for image in waiting:
            store.add_image(image, image_bits(image["width_px"], image["height_px"]))

    def rover_report(self, t_s: float, report: Mapping[str, Any]) -> None:
        self.link.store.add_report(t_s, report)

    # ---- the clock ----------------------------------------------------------------------

    def advance(self, t_s: float) -> None:
        """The link up to ``t_s``, and everything it brought handed on."""
        progress = self.link.advance(t_s)
        if progress.radiated or progress.onboard or progress.on_ground or progress.unsent:
            self.hand_on(progress)

    def onboard_until(self, t_s: float) -> None:
        """What has reached the rover by its clock ``t_s`` (before it starts a step)."""
        arrived = self.link.onboard_until(t_s)
        if arrived:
            self.hand_on(Progress(onboard=arrived))

    def hand_on(self, progress: Progress) -> None:
        for uplink in progress.unsent:
            window = self.plan.uplink_minutes * 60.0 * self.plan.uplink_rate_bps
            detail = (
                f"not radiated: no uplink window in the next {SEARCH_SOLS} sols holds "
                f"its {uplink.bits} bits (a whole window holds at most {window:.0f})"
            )
            self.host.stage(uplink.sequence_id, "not radiated", self.link.t_s, detail)
            self.host.status_arrived(uplink.sequence_id, "failed", detail)
        for uplink in progress.radiated:
            assert uplink.radiated_t_s is not None
            what = "radiated" if uplink.kind == "sequence" else "cancel radiated"
            self.host.stage(uplink.sequence_id, what, uplink.radiated_t_s)
            if uplink.kind == "sequence":
                self.radiated_ids.add(uplink.sequence_id)
        for uplink in progress.onboard:
            at = uplink.arrival_t_s
            assert at is not None
            if uplink.kind == "sequence":
                self.host.take_uplink(QueuedSequence.from_state(uplink.payload), at)
                report = {"type": "stage", "sequence_id": uplink.sequence_id, "stage": "received"}
            else:
                found = self.host.cancel_onboard(uplink.sequence_id)
                report = {"type": "cancel", "sequence_id": uplink.sequence_id, **found}
            self.rover_report(at, report)
        frames: list[DownlinkDict] = []
        images: list[ImageDict] = []
        for sent in progress.on_ground:
            self._count(sent)
            if sent.product.kind == "frame":
                frames.append(sent.product.payload)  # type: ignore[arg-type]
            elif sent.product.kind == "image":
                images.append(as_image(sent.product.payload))
            else:
                self._report_arrived(sent)
        if frames or images:  # one batch, stamped with its last arrival: never earlier than any
            received = progress.on_ground[-1].arrival_t_s
            batch = FrameBatch(frames, [], received, images)
            self.host.downlink_arrived(batch, recovering=received <= self.received_until_t_s)

    def _report_arrived(self, sent: Sent) -> None:
        report, t_s = sent.product.payload, sent.product.t_s
        recovering = sent.arrival_t_s <= self.received_until_t_s
        kind, sequence_id = report.get("type"), int(report.get("sequence_id") or 0)
        if kind == "store":  # the newest account made (a relay's may come after a newer DTE's)
            if self.store_reported is None or t_s >= self.store_reported["t_s"]:
                self.store_reported = {**report, "t_s": t_s, "received_t_s": sent.arrival_t_s}
        elif kind == "command":
            self.host.command_arrived(report)
        elif kind == "stage":
            self.host.stage(sequence_id, str(report["stage"]), t_s)
        elif kind == "sequence":
            status, detail = str(report["status"]), report.get("detail")
            self.host.status_arrived(sequence_id, status, detail, t_s)
            self.host.stage(sequence_id, stage_of(status, detail), t_s, detail)
            if status != "running":
                self.radiated_ids.discard(sequence_id)
        elif kind == "cancel":
            self.radiated_ids.discard(sequence_id)
            if report.get("found"):
                detail = f"cancelled onboard {report['where']}"
                self.host.status_arrived(sequence_id, "cancelled", detail, t_s)
                self.host.stage(sequence_id, "cancelled", t_s, detail)
            else:
                text = (
                    f"the cancel of sequence #{sequence_id} reached the rover after the "
                    "sequence had ended: nothing to cancel"
                )
                self.host.event(t_s, {"text": text, "kind": "sequence", "severity": "warning"},
                                recovering, sent.arrival_t_s)  # fmt: skip
        elif kind == "gap":
            self.gaps = [
                *self.gaps[-PASSES_KEPT + 1 :],
                {**report, "received_t_s": sent.arrival_t_s},
            ]
            self.host.event(t_s, {"text": gap_text(report), "kind": "comm", "severity": "warning"},
                            recovering, sent.arrival_t_s)  # fmt: skip

    def _count(self, sent: Sent) -> None:
        """What each pass brought, as the ground tallies it on arrival."""
        key = f"{sent.via} {sent.pass_start_t_s:.3f}"
        tally = self.passes.setdefault(
            key,
            {
                "start_t_s": sent.pass_start_t_s,
                "via": sent.via,
                "bits": 0,
                "products": 0,
                "first_received_t_s": sent.arrival_t_s,
            },
        )
        tally["bits"] += sent.product.bits
        tally["products"] += 1
        tally["last_received_t_s"] = sent.arrival_t_s
        while len(self.passes) > PASSES_KEPT:
            del self.passes[min(self.passes, key=lambda k: self.passes[k]["start_t_s"])]

    # ---- what the ground knows -----------------------------------------------------------

    def ground_view(self) -> dict[str, Any]:
        """What the ground knows of its link (never what the rover holds unreported, nor
        what is on its way down): what waits to go up and what it radiated, the store as
        last reported, what each pass brought, the gaps reported."""
        return {
            "waiting": [_uplink_json(u) for u in self.link.waiting],
            "rising": [_uplink_json(u) for u in self.link.rising],
            "store": self.store_reported,
            "passes": sorted(self.passes.values(), key=lambda p: p["start_t_s"]),
            "gaps": list(self.gaps),
            "radiated_ids": sorted(self.radiated_ids),
        }

    # ---- checkpoint -------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        return {
            "link": self.link.state(),
            "store_reported": self.store_reported,
            "passes": self.passes,
            "gaps": self.gaps,
            "radiated_ids": sorted(self.radiated_ids),
        }

    def load_state(self, state: Mapping[str, Any]) -> None:
        link = self.link
        self.link = CommLink.from_state(link.lat_deg, link.lon_east_deg, state["link"])
        self.store_reported = state["store_reported"]
        self.passes = dict(state["passes"])
        self.gaps = list(state["gaps"])
        self.radiated_ids = {int(i) for i in state["radiated_ids"]}


def _uplink_json(uplink: Uplink) -> dict[str, Any]:
    return {"uplink_id": uplink.id, "kind": uplink.kind, "sequence_id": uplink.sequence_id,
            "bits": uplink.bits, "accepted_t_s": uplink.accepted_t_s,
            "radiated_t_s": uplink.radiated_t_s, "arrival_t_s": uplink.arrival_t_s}  # fmt: skip


def stage_of(status: str, detail: str | None) -> str:
    """A sequence's status as a stage of its command history: ``started`` when it runs;
    ``halted`` when fault protection stopped it."""
    if status == "running":
        return "started"
    if status == "failed" and detail and " halted" in detail:
        return "halted"
    return status


def gap_text(gap: Mapping[str, Any]) -> str:
    """A gap the store reports, in words."""
    what = {0: "reports", 1: "decimated telemetry frames and images", 2: "telemetry frames"}
    span_min = (float(gap["last_t_s"]) - float(gap["first_t_s"])) / 60.0
    return (
        f"downlink gap: the onboard store was full and dropped {gap['count']} "
        f"{what.get(int(gap['priority']), 'products')} ({gap['bits'] / 1e6:.3f} Mbit) made "
        f"over {span_min:.1f} min of the rover's clock; they will never come down"
    )
