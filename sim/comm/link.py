"""The link between the ground and a rover across light time: what goes up, when it arrives
onboard, what comes down in which pass, and when it reaches the ground.

Everything runs on one clock, the rover's ``t_s`` (TT seconds since J2000), which is also the
ground's: so a speed factor scales light time, windows and passes alike.

**Up.** The ground accepts an uplink (a sequence, an immediate command, a cancel) at once and
radiates it in the next uplink window (``sim.comm.windows``: the morning direct-to-Earth
session through the high-gain antenna, Earth high enough). Uplinks go out one after another,
each taking its bits over the window's rate, and one that cannot be radiated whole before the
window closes waits for the next window. It reaches the rover when the light that left
Earth at the end of its radiation arrives (``light.uplink_arrival_t_s``). Nothing is radiated
outside a window.

**Down.** The rover's products wait in its store (``sim.comm.store``). A relay pass (the orbiter
above its mask) or a direct-to-Earth session sends them, highest priority first, each taking
its bits over the link's rate from the moment the previous one is out; where a relay pass
and a direct-to-Earth session overlap, the faster link carries the data. A product made during
a pass can go in the same pass; one that does not fit before the pass ends (the orbiter
setting) waits for the next. What is sent reaches the ground at its send time plus the relay's
store-and-forward delay (relay only) plus the light time (``light.downlink_arrival_t_s``), never
earlier.

``CommLink.advance(t_to_s)`` does all of this up to ``t_to_s`` and returns what happened
(``Progress``): the uplinks radiated and the ones now onboard, the products now on the ground.
The caller adds the rover's products as its clock reaches them, before advancing past them.
The whole link (the ground's uplink queue, what is in transit both ways, the store, the
transmitter's place in a pass) is plain data for the checkpoint (``state``/``from_state``).
"""

from __future__ import annotations

import bisect
import itertools
import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any, Literal, Protocol

from sim.comm.plan import CommPlan
from sim.comm.store import OnboardStore, Product
from sim.comm.windows import Window, comm_windows
from sim.world.light_time import downlink_arrival_t_s, uplink_arrival_t_s
from sim.world.marsclock import SOL_S

UplinkKind = Literal["sequence", "cancel"]
WindowsFn = Callable[[float, float, CommPlan, float, float], list[Window]]
SEARCH_SOLS = 10  # how far ahead an uplink looks for a window before it waits and looks again
DOWNLINK_KINDS = ("relay", "dte")


class LightTime(Protocol):
    """When a signal arrives: radiated from Earth to Mars, sent from Mars to Earth."""

    def uplink_arrival_t_s(self, t_radiated_s: float) -> float: ...

    def downlink_arrival_t_s(self, t_sent_s: float) -> float: ...


class De421LightTime:
    """The light time from JPL's ephemeris (``sim.world.light_time``)."""

    def uplink_arrival_t_s(self, t_radiated_s: float) -> float:
        return uplink_arrival_t_s(t_radiated_s)

    def downlink_arrival_t_s(self, t_sent_s: float) -> float:
        return downlink_arrival_t_s(t_sent_s)


@dataclass
class Uplink:
    """Something the ground radiates: a sequence (``payload``: its queue entry's plain data)
    or a cancel of sequence ``sequence_id``."""

    id: int
    kind: UplinkKind
    sequence_id: int
    bits: int
    accepted_t_s: float
    payload: dict[str, Any] = field(default_factory=dict)
    radiated_t_s: float | None = None  # its last bit left Earth
    arrival_t_s: float | None = None  # its last bit reached the rover

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> Uplink:
        return cls(**dict(state))


@dataclass(frozen=True)
class Sent:
    """A product on its way down: sent at ``sent_t_s`` in the pass that began at
    ``pass_start_t_s`` (its ``via``), on the ground at ``arrival_t_s``."""

    arrival_t_s: float
    sent_t_s: float
    pass_start_t_s: float
    via: str
    product: Product

    def state(self) -> dict[str, Any]:
        return {**asdict(self), "product": self.product.state()}

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> Sent:
        return cls(
            float(state["arrival_t_s"]),
            float(state["sent_t_s"]),
            float(state["pass_start_t_s"]),
            str(state["via"]),
            Product.from_state(state["product"]),
        )


@dataclass
class Progress:
    """What one ``advance`` brought about, each list in time order."""

    radiated: list[Uplink] = field(default_factory=list)
    onboard: list[Uplink] = field(default_factory=list)
    unsent: list[Uplink] = field(default_factory=list)  # too big for every window ahead
    on_ground: list[Sent] = field(default_factory=list)


@dataclass(frozen=True)
class _Segment:
    """A stretch of time in which one downlink window carries the data."""

    start_t_s: float
    end_t_s: float
    window: Window


class CommLink:
    """The link of one rover at ``lat_deg``/``lon_east_deg`` (module docstring)."""

    def __init__(
        self,
        lat_deg: float,
        lon_east_deg: float,
        plan: CommPlan,
        t_s: float,
        windows: WindowsFn = comm_windows,
        light: LightTime | None = None,
    ) -> None:
        self.lat_deg = lat_deg
        self.lon_east_deg = lon_east_deg
        self.plan = plan
        self._windows = windows
        self.light: LightTime = light or De421LightTime()
        self.store = OnboardStore(int(plan.store_capacity_mbit * 1e6), plan.decimate_s)
        self.waiting: list[Uplink] = []  # accepted by the ground, not yet radiated
        self.rising: list[Uplink] = []  # radiated, not yet onboard, by arrival
        self.falling: list[Sent] = []  # sent, not yet on the ground, by arrival
        self.next_uplink_id = 1
        self.down_t_s = t_s  # the transmitter's place: everything before it is done
        self.up_t_s = t_s  # the end of the last radiation
        self.t_s = t_s  # advanced to here
        self.opened_t_s = -math.inf  # the last pass the store gave its account at

    # ---- the plan ---------------------------------------------------------------------

    def windows(self, t_from_s: float, t_to_s: float) -> list[Window]:
        """The link's windows overlapping [t_from_s, t_to_s] (``sim.comm.windows``)."""
        return self._windows(self.lat_deg, self.lon_east_deg, self.plan, t_from_s, t_to_s)

    def set_plan(self, plan: CommPlan) -> None:
        """A new plan from now on; the store keeps what it holds (a smaller capacity drops
        the lowest priority at its next product)."""
        self.plan = plan
        self.store.capacity_bits = int(plan.store_capacity_mbit * 1e6)
        self.store.decimate_s = plan.decimate_s

    # ---- up -----------------------------------------------------------------------------

    def accept(
        self,
        kind: UplinkKind,
        sequence_id: int,
        bits: int,
        t_s: float,
        payload: Mapping[str, Any] | None = None,
    ) -> Uplink:
        """Take an uplink in on the ground at ``t_s``; it waits for its window."""
        uplink = Uplink(
            self.next_uplink_id, kind, sequence_id, max(1, int(bits)), t_s, dict(payload or {})
        )
        self.next_uplink_id += 1
        self.waiting.append(uplink)
        return uplink

    def withdraw(self, sequence_id: int) -> Uplink | None:
        """Take a sequence back before it is radiated (``None`` if none waits)."""
        for uplink in self.waiting:
            if uplink.kind == "sequence" and uplink.sequence_id == sequence_id:
                self.waiting.remove(uplink)
                return uplink
        return None

    def radiation(self, uplink: Uplink, after_t_s: float) -> tuple[float, float] | None:
        """When ``uplink`` would be radiated, starting no earlier than ``after_t_s``: (first
        bit, last bit) inside one uplink window, or ``None`` if no window in SEARCH_SOLS."""
        t = after_t_s
        horizon = after_t_s + SEARCH_SOLS * SOL_S
        while t < horizon:
            for w in self.windows(t, t + SOL_S):
                if w.kind != "uplink" or w.end_t_s <= t:
                    continue
                begin = max(t, w.start_t_s)
                end = begin + uplink.bits / w.rate_bps
                if end <= w.end_t_s:
                    return begin, end
            t += SOL_S
        return None

    def _advance_up(self, t_to_s: float, progress: Progress) -> None:
        while self.waiting:
            uplink = self.waiting[0]
            when = self.radiation(uplink, max(uplink.accepted_t_s, self.up_t_s))
            if when is None:  # no window of SEARCH_SOLS holds it: it would block the rest
                progress.unsent.append(self.waiting.pop(0))
                continue
            if when[1] > t_to_s:
                break
            self.waiting.pop(0)
            uplink.radiated_t_s = when[1]
            uplink.arrival_t_s = self.light.uplink_arrival_t_s(when[1])
            self.up_t_s = when[1]
            bisect.insort(self.rising, uplink, key=lambda u: (u.arrival_t_s, u.id))
            progress.radiated.append(uplink)
        progress.onboard += self.onboard_until(t_to_s)

    def onboard_until(self, t_s: float) -> list[Uplink]:
        """The uplinks on their way that have reached the rover by ``t_s`` (the rover's
        clock, which may run ahead of the ground's while a command executes)."""
        arrived = []
        while self.rising and _arrival(self.rising[0]) <= t_s:
            arrived.append(self.rising.pop(0))
        return arrived

    # ---- down ---------------------------------------------------------------------------

    def _segments(self, t_from_s: float, t_to_s: float) -> list[_Segment]:
        """The downlink windows over [t_from_s, t_to_s] as stretches that do not overlap:
        where two overlap, the faster one."""
        found = [w for w in self.windows(t_from_s, t_to_s) if w.kind in DOWNLINK_KINDS]
        edges = sorted(
            {t_from_s, t_to_s, *(w.start_t_s for w in found), *(w.end_t_s for w in found)}
        )
        out: list[_Segment] = []
        for a, b in itertools.pairwise(edges):
            if b <= t_from_s or a >= t_to_s or b <= a:
                continue
            up = [w for w in found if w.start_t_s <= a and w.end_t_s >= b]
            if not up:
                continue
            best = max(up, key=lambda w: (w.rate_bps, w.kind == "relay"))
            if out and out[-1].window == best and out[-1].end_t_s == a:
                out[-1] = _Segment(out[-1].start_t_s, b, best)
            else:
                out.append(_Segment(a, b, best))
        return out

    def _arrival(self, sent_t_s: float, window: Window) -> float:
        latency = self.plan.relay_latency_s if window.kind == "relay" else 0.0
        return self.light.downlink_arrival_t_s(sent_t_s + latency)

    def _advance_down(self, t_to_s: float, progress: Progress) -> None:
        store = self.store
        for segment in self._segments(self.down_t_s, t_to_s):
            window = segment.window
            t = max(segment.start_t_s, self.down_t_s)
            if t == window.start_t_s > self.opened_t_s:  # a pass opens: the store's account
                self.opened_t_s = t
                store.add_report(
                    t,
                    {
                        "type": "store",
                        "used_bits": store.used_bits,
                        "capacity_bits": store.capacity_bits,
                        "held": len(store),
                        "dropped": store.stats.dropped,
                    },
                )
            stop = min(segment.end_t_s, t_to_s)
            while t < stop:
                product = store.next_ready(t)
                if product is None:
                    t = min(max(store.next_made_t_s(), t), stop)
                    continue
                done = t + product.bits / window.rate_bps
                if done > window.end_t_s:  # the orbiter sets first: it waits for a pass
                    t = stop
                    break
                if done > t_to_s:  # still going out: taken up again at the next advance
                    self.down_t_s = t
                    self._deliver_down(t_to_s, progress)
                    return
                store.remove(product)
                sent = Sent(
                    self._arrival(done, window), done, window.start_t_s, window.kind, product
                )
                bisect.insort(self.falling, sent, key=lambda s: (s.arrival_t_s, s.product.id))
                t = done
        self.down_t_s = max(self.down_t_s, t_to_s)
        self._deliver_down(t_to_s, progress)

    def _deliver_down(self, t_to_s: float, progress: Progress) -> None:
        # every tick: search the sorted list without copying its thousands of arrival times
        n = bisect.bisect_right(self.falling, t_to_s, key=lambda s: s.arrival_t_s)
        progress.on_ground.extend(self.falling[:n])
        del self.falling[:n]

    # ---- the clock ----------------------------------------------------------------------

    def advance(self, t_to_s: float) -> Progress:
        """Everything up to ``t_to_s`` (module docstring); a time before the last is a no-op."""
        progress = Progress()
        if not t_to_s > self.t_s:
            return progress
        self._advance_up(t_to_s, progress)
        self._advance_down(t_to_s, progress)
        self.t_s = t_to_s
        return progress

    def drain(self, t_s: float) -> Progress:
        """Everything through at once at ``t_s`` (the link made instant again): what waits
        is radiated and onboard, what the store holds and what is on its way is on the
        ground."""
        progress = Progress()
        for uplink in self.waiting:
            uplink.radiated_t_s = uplink.arrival_t_s = t_s
            progress.radiated.append(uplink)
        progress.onboard = [*self.rising, *self.waiting]
        self.waiting, self.rising = [], []
        progress.on_ground = list(self.falling)
        self.falling = []
        while (product := self.store.next_ready(math.inf)) is not None:
            self.store.remove(product)
            progress.on_ground.append(Sent(t_s, t_s, t_s, "drain", product))
        self.t_s = self.down_t_s = self.up_t_s = max(self.t_s, t_s)
        return progress

    def next_due_t_s(self) -> float:
        """The next moment the link brings something (an uplink radiated or onboard, a
        product on the ground), as far as can be known now: a clock with nothing else to
        do skips to it."""
        due = [math.inf]
        if self.rising:
            due.append(_arrival(self.rising[0]))
        if self.falling:
            due.append(self.falling[0].arrival_t_s)
        if self.waiting:
            when = self.radiation(self.waiting[0], max(self.waiting[0].accepted_t_s, self.up_t_s))
            if when is not None:
                due.append(when[1])
        if len(self.store):
            ahead = [s for s in self._segments(self.down_t_s, self.down_t_s + SOL_S)]
            if ahead:
                due.append(ahead[0].end_t_s)
        return min(due)

    # ---- checkpoint ---------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        return {
            "plan": self.plan.as_json(),
            "store": self.store.state(),
            "waiting": [asdict(u) for u in self.waiting],
            "rising": [asdict(u) for u in self.rising],
            "falling": [s.state() for s in self.falling],
            "next_uplink_id": self.next_uplink_id,
            "down_t_s": self.down_t_s,
            "up_t_s": self.up_t_s,
            "t_s": self.t_s,
            "opened_t_s": self.opened_t_s,
        }

    @classmethod
    def from_state(
        cls,
        lat_deg: float,
        lon_east_deg: float,
        state: Mapping[str, Any],
        windows: WindowsFn = comm_windows,
        light: LightTime | None = None,
    ) -> CommLink:
        link = cls(
            lat_deg,
            lon_east_deg,
            CommPlan.from_json(state["plan"]),
            float(state["t_s"]),
            windows,
            light,
        )
        link.store = OnboardStore.from_state(state["store"])
        link.waiting = [Uplink.from_state(u) for u in state["waiting"]]
        link.rising = [Uplink.from_state(u) for u in state["rising"]]
        link.falling = [Sent.from_state(s) for s in state["falling"]]
        link.next_uplink_id = int(state["next_uplink_id"])
        link.down_t_s = float(state["down_t_s"])
        link.up_t_s = float(state["up_t_s"])
        link.opened_t_s = float(state["opened_t_s"])
        return link


def _arrival(uplink: Uplink) -> float:
    assert uplink.arrival_t_s is not None
    return uplink.arrival_t_s
