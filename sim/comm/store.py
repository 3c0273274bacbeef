"""The rover's onboard store: what it has made and not yet sent, by priority, in a set capacity.

Every product the rover makes for the ground (a telemetry frame, a command report, a
sequence's status, an acknowledgement) waits here until a pass sends it. A product has a
size in bits (``packed_bits``: the record packed as a flight data system would pack it, not
as JSON) and a priority, 0 the highest:

- 0 ``PRIORITY_REPORT``: command reports, acknowledgements, gaps, the store's own status,
  and every telemetry frame that carries an event (the event rides its frame);
- 1 ``PRIORITY_DECIMATED``: the telemetry decimated, one frame per ``decimate_s`` of the
  rover's clock and every frame whose NATE mode changed; and the images (``add_image``:
  Navcam pairs, ``sim.loop.images``), which the drivers plan the next sol from, as MER's
  tactical downlink put its Navcam images ahead of the full-rate engineering data;
- 2 ``PRIORITY_FULL``: the rest of the telemetry, at full rate.

A pass takes the highest priority first and, within one, the oldest (``next_ready``).

When the store overflows, the lowest priority goes first, oldest first. Nothing is dropped
silently: the drops of one priority are counted in a gap product (priority 0, its span of
the rover's clock, its count and its bits) that grows while the drops go on and is closed
once it is sent, so the ground learns of every product it will never see.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

ProductKind = Literal["frame", "report", "gap", "image"]
PRIORITY_REPORT, PRIORITY_DECIMATED, PRIORITY_FULL = 0, 1, 2
PRIORITIES = (PRIORITY_REPORT, PRIORITY_DECIMATED, PRIORITY_FULL)
HEADER_BITS = 48  # a CCSDS space packet's primary header
NUMBER_BITS = 32  # a telemetry channel (float32 or int32)
GAP_BITS = HEADER_BITS + 6 * NUMBER_BITS


def packed_bits(value: Any) -> int:
    """The bits of ``value`` packed: 32 a number, 8 a flag or an absent value, 8 a
    character; lists and mappings their items (a mapping's keys are the packet's layout,
    known on both ends, so they cost nothing)."""
    if isinstance(value, bool) or value is None:
        return 8
    if isinstance(value, int | float):
        return NUMBER_BITS
    if isinstance(value, str):
        return 8 * len(value)
    if isinstance(value, Mapping):
        return sum(packed_bits(v) for v in value.values())
    if isinstance(value, list | tuple):
        return sum(packed_bits(v) for v in value)
    raise TypeError(f"cannot pack a {type(value).__name__}")


@dataclass
class Product:
    """One thing the rover sends: ``payload`` is a downlink record (``frame``), a report
    (``report``: a dict with its ``type``) or a gap's account (``gap``)."""

    id: int
    kind: ProductKind
    priority: int
    t_s: float  # the rover's clock when it was made
    bits: int
    payload: dict[str, Any]

    def state(self) -> dict[str, Any]:
        return asdict(self)

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> Product:
        return cls(
            int(state["id"]),
            state["kind"],
            int(state["priority"]),
            float(state["t_s"]),
            int(state["bits"]),
            dict(state["payload"]),
        )


@dataclass
class StoreStats:
    """What the store has taken in and let go of since the rover started."""

    added: int = 0
    sent: int = 0
    dropped: int = 0
    dropped_bits: int = 0


@dataclass
class OnboardStore:
    """Products by priority, each priority oldest first, within ``capacity_bits``."""

    capacity_bits: int
    decimate_s: float = 60.0
    used_bits: int = 0
    next_id: int = 1
    stats: StoreStats = field(default_factory=StoreStats)
    _queues: dict[int, deque[Product]] = field(default_factory=dict)
    _open_gaps: dict[int, Product] = field(default_factory=dict)  # priority -> its gap, unsent
    _last_decimated_t_s: float = -math.inf
    _last_mode: str | None = None

    def __post_init__(self) -> None:
        for p in PRIORITIES:
            self._queues.setdefault(p, deque())

    # ---- taking products in -----------------------------------------------------------

    def add_frame(self, frame: Mapping[str, Any]) -> None:
        """A telemetry frame (a downlink record), its priority from its events, its mode
        and the decimation."""
        t_s = float(frame["t_s"])
        mode = frame.get("nate_mode")
        if frame.get("events"):
            priority = PRIORITY_REPORT
        elif t_s - self._last_decimated_t_s >= self.decimate_s or mode != self._last_mode:
            priority = PRIORITY_DECIMATED
        else:
            priority = PRIORITY_FULL
        if priority != PRIORITY_FULL:
            self._last_decimated_t_s = t_s
        self._last_mode = mode
        self._add("frame", priority, t_s, HEADER_BITS + packed_bits(frame), dict(frame))

    def add_image(self, image: Mapping[str, Any], image_bits: int) -> None:
        """An image product (``sim.loop.images.ImageDict``): its compressed frames'
        ``image_bits`` and its metadata packed; priority 1 (module docstring)."""
        meta = {k: v for k, v in image.items() if k not in ("left", "right")}
        bits = HEADER_BITS + packed_bits(meta) + int(image_bits)
        self._add("image", PRIORITY_DECIMATED, float(image["t_s"]), bits, dict(image))

    def add_report(self, t_s: float, report: Mapping[str, Any]) -> None:
        """A report (a dict with its ``type``) at the rover's clock ``t_s``: priority 0."""
        self._add("report", PRIORITY_REPORT, t_s, HEADER_BITS + packed_bits(report), dict(report))

    def _add(
        self, kind: ProductKind, priority: int, t_s: float, bits: int, payload: dict[str, Any]
    ) -> None:
        product = Product(self.next_id, kind, priority, t_s, bits, payload)
        self.next_id += 1
        self._queues[priority].append(product)
        self.used_bits += bits
        self.stats.added += 1
        self._make_room(t_s)

    def _make_room(self, t_s: float) -> None:
        """Drop the lowest priority, oldest first, until the store fits its capacity. The
        gaps themselves are never dropped: they are what the ground learns the drops from."""
        while self.used_bits > self.capacity_bits:
            victim = self._oldest_droppable()
            if victim is None:
                return  # only gaps left: over capacity by their few bits until a pass
            self._queues[victim.priority].remove(victim)
            self.used_bits -= victim.bits
            self.stats.dropped += 1
            self.stats.dropped_bits += victim.bits
            self._count_in_gap(victim, t_s)

    def _oldest_droppable(self) -> Product | None:
        for priority in reversed(PRIORITIES):
            for product in self._queues[priority]:
                if product.kind != "gap":
                    return product
        return None

    def _count_in_gap(self, dropped: Product, t_s: float) -> None:
        gap = self._open_gaps.get(dropped.priority)
        if gap is None:
            payload = {
                "type": "gap",
                "priority": dropped.priority,
                "kind": dropped.kind,
                "first_t_s": dropped.t_s,
                "last_t_s": dropped.t_s,
                "count": 0,
                "bits": 0,
                "noted_t_s": t_s,
            }
            gap = Product(self.next_id, "gap", PRIORITY_REPORT, t_s, GAP_BITS, payload)
            self.next_id += 1
            self._queues[PRIORITY_REPORT].append(gap)
            self.used_bits += gap.bits
            self._open_gaps[dropped.priority] = gap
        span = gap.payload
        span["first_t_s"] = min(span["first_t_s"], dropped.t_s)
        span["last_t_s"] = max(span["last_t_s"], dropped.t_s)
        span["count"] += 1
        span["bits"] += dropped.bits

    # ---- sending ------------------------------------------------------------------------

    def next_ready(self, t_s: float) -> Product | None:
        """The product a pass sends next at ``t_s``: the highest priority, the oldest of
        those made by then."""
        for priority in PRIORITIES:
            queue = self._queues[priority]
            if queue and queue[0].t_s <= t_s:
                return queue[0]
        return None

    def next_made_t_s(self) -> float:
        """When the earliest product still held was made (``inf`` when empty)."""
        heads = [q[0].t_s for q in self._queues.values() if q]
        return min(heads, default=math.inf)

    def remove(self, product: Product) -> None:
        """``product`` has been sent (it was ``next_ready``): it leaves the store; a gap is
        closed, so later drops open a new one."""
        self._queues[product.priority].popleft()
        self.used_bits -= product.bits
        self.stats.sent += 1
        if product.kind == "gap":
            self._open_gaps.pop(int(product.payload["priority"]), None)

    def __len__(self) -> int:
        return sum(len(q) for q in self._queues.values())

    def fill_fraction(self) -> float:
        return self.used_bits / self.capacity_bits

    def counts(self) -> dict[int, int]:
        """Products held by priority."""
        return {p: len(q) for p, q in self._queues.items()}

    # ---- checkpoint -------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        return {
            "capacity_bits": self.capacity_bits,
            "decimate_s": self.decimate_s,
            "next_id": self.next_id,
            "stats": asdict(self.stats),
            "products": [p.state() for q in self._queues.values() for p in q],
            "open_gaps": {str(k): g.id for k, g in self._open_gaps.items()},
            "last_decimated_t_s": self._last_decimated_t_s,
            "last_mode": self._last_mode,
        }

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> OnboardStore:
        store = cls(int(state["capacity_bits"]), float(state["decimate_s"]))
        store.next_id = int(state["next_id"])
        store.stats = StoreStats(**state["stats"])
        by_id: dict[int, Product] = {}
        for data in state["products"]:
            product = Product.from_state(data)
            store._queues[product.priority].append(product)
            store.used_bits += product.bits
            by_id[product.id] = product
        store._open_gaps = {int(k): by_id[int(i)] for k, i in state["open_gaps"].items()}
        store._last_decimated_t_s = float(state["last_decimated_t_s"])
        store._last_mode = state["last_mode"]
        return store
