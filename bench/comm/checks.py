"""The checks a run across light time must pass, shared by the in-process sols and the
killed server: nothing arrives before the light could bring it, nothing goes up outside
an uplink window, and what is stored, read back.

The light times come from ``bench.comm.light`` (the second computation, not the
simulator's), interpolated on a grid (``LightTable``: a light time changes by at most
1e-4 s a second, so a 10-minute grid interpolates it to well under a microsecond).
Every comparison allows ``TOL_S`` (1 ms): the simulator's own solution is good to 1e-7 s.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sqlalchemy import select

from bench.comm.light import downlink_s, emitted_t_s, uplink_s
from server.storage import Store
from server.storage.schema import events, frames_table, truth_frames
from sim.comm.link import CommLink, Progress, Sent, Uplink
from sim.comm.windows import Window

TOL_S = 1e-3  # what an arrival may come early by and still count as on time
GRID_S = 600.0  # the light-time tables' step


class LightTable:
    """``fn`` (a light time, or an emission time, of a time) on a grid over [t_from_s,
    t_to_s], interpolated linearly."""

    def __init__(self, fn: Callable[[float], float], t_from_s: float, t_to_s: float) -> None:
        n = max(2, math.ceil((t_to_s - t_from_s) / GRID_S) + 1)
        self.t_s = np.linspace(t_from_s - GRID_S, t_to_s + GRID_S, n + 2)
        self.values = np.array([fn(float(t)) for t in self.t_s])

    def __call__(self, t_s: float) -> float:
        return float(np.interp(t_s, self.t_s, self.values))


@dataclass
class LinkTap:
    """Everything a ``CommLink`` brings about (its ``Progress``, from ``advance`` and
    ``drain``), recorded as it happens: the link's own account, before the server turns
    it into stored rows."""

    sent: list[Sent] = field(default_factory=list)
    radiated: list[Uplink] = field(default_factory=list)
    onboard: list[Uplink] = field(default_factory=list)

    def attach(self, link: CommLink) -> None:
        """Record every ``Progress`` of ``link`` from now on (its methods wrapped)."""
        advance, drain = link.advance, link.drain

        def recorded(progress: Progress) -> Progress:
            self.sent += progress.on_ground
            self.radiated += progress.radiated
            self.onboard += progress.onboard
            return progress

        link.advance = lambda t_to_s: recorded(advance(t_to_s))  # type: ignore[method-assign]
        link.drain = lambda t_s: recorded(drain(t_s))  # type: ignore[method-assign]


def early_sent(sent: Iterable[Sent], relay_latency_s: float) -> list[str]:
    """Each product on the ground earlier than its send time plus the relay's delay (relay
    only) plus the light time, or sent before it was made: what is wrong, in words."""
    found = list(sent)
    if not found:
        return []
    start = min(s.sent_t_s for s in found)
    table = LightTable(downlink_s, start, max(s.sent_t_s for s in found) + relay_latency_s)
    wrong = []
    for s in found:
        left_t_s = s.sent_t_s + (relay_latency_s if s.via == "relay" else 0.0)
        due_t_s = left_t_s + table(left_t_s)
        if s.arrival_t_s < due_t_s - TOL_S:
            early_s = due_t_s - s.arrival_t_s
            wrong.append(f"product {s.product.id} on the ground {early_s:.3f} s early")
        if s.sent_t_s < s.product.t_s - TOL_S:
            wrong.append(f"product {s.product.id} sent before it was made")
    return wrong


def early_rows(rows: Iterable[tuple[float, float | None]]) -> list[str]:
    """Each stored row (``t_s`` made, ``received_t_s`` on the ground) whose arrival left
    Mars before the row was made: received earlier than its time plus the light time."""
    found = [(t, r) for t, r in rows if r is not None]
    if not found:
        return []
    table = LightTable(emitted_t_s, min(r for _, r in found), max(r for _, r in found))
    return [
        f"row of {t:.3f} received {t - table(r):.3f} s early"
        for t, r in found
        if table(r) < t - TOL_S
    ]


def in_window(windows: Iterable[Window], kind: str, start_t_s: float, end_t_s: float) -> bool:
    """Whether [start_t_s, end_t_s] lies inside one window of ``kind``."""
    return any(
        w.kind == kind and w.start_t_s - TOL_S <= start_t_s and end_t_s <= w.end_t_s + TOL_S
        for w in windows
    )


def uplink_faults(uplinks: Iterable[Uplink], rate_bps: float, windows: list[Window]) -> list[str]:
    """Each uplink the link radiated not wholly inside an uplink window (its first bit
    ``bits / rate_bps`` before its last), or onboard before its light time."""
    wrong = []
    for u in uplinks:
        if u.radiated_t_s is None or u.arrival_t_s is None:
            wrong.append(f"uplink {u.id} without its times")
            continue
        first = u.radiated_t_s - u.bits / rate_bps
        if not in_window(windows, "uplink", first, u.radiated_t_s):
            wrong.append(f"uplink {u.id} radiated outside an uplink window")
        if u.arrival_t_s < u.radiated_t_s + uplink_s(u.radiated_t_s) - TOL_S:
            wrong.append(f"uplink {u.id} onboard before its light time")
    return wrong


def stage_faults(sequences: Iterable[Mapping[str, Any]], windows: list[Window]) -> list[str]:
    """The command history of each sequence the link carried (one with a ``waiting``
    stage): radiated inside an uplink window, received no sooner than the light allows,
    started no sooner than received."""
    wrong = []
    for seq in sequences:
        stages = {s["stage"]: float(s["t_s"]) for s in seq.get("stages") or []}
        if "waiting" not in stages or "radiated" not in stages:
            continue  # sent with the link instant, or not radiated yet
        name, radiated = seq["name"], stages["radiated"]
        if not in_window(windows, "uplink", radiated, radiated):
            wrong.append(f"{name}: radiated outside an uplink window")
        received = stages.get("received")
        if received is not None and received < radiated + uplink_s(radiated) - TOL_S:
            wrong.append(f"{name}: received before its light time")
        started = stages.get("started")
        if started is not None and (received is None or started < received - TOL_S):
            wrong.append(f"{name}: started before it was received")
    return wrong


# ---- what a database holds ------------------------------------------------------------------


@dataclass
class Stored:
    """A rover's rows in a server's database, read once its server has stopped."""

    frames: list[tuple[float, float | None]]  # (t_s, received_t_s)
    truth_t_s: list[float]
    events: list[tuple[float, str, str, float | None]]  # (t_s, kind, text, received_t_s)
    commands: list[dict[str, Any]]
    sequences: list[dict[str, Any]]  # with their stages

    @classmethod
    def read(cls, url: str, rover: str) -> Stored:
        store = Store(url)
        try:
            with store.engine.connect() as conn:
                f, t, e = frames_table.c, truth_frames.c, events.c
                frames = [
                    (float(a), None if b is None else float(b))
                    for a, b in conn.execute(select(f.t_s, f.received_t_s).where(f.rover == rover))
                ]
                truth = [float(a) for (a,) in conn.execute(select(t.t_s).where(t.rover == rover))]
                rows = conn.execute(
                    select(e.t_s, e.kind, e.text, e.received_t_s).where(e.rover == rover)
                )
                found = [(float(a), str(b), str(c), None if d is None else float(d))
                         for a, b, c, d in rows]  # fmt: skip
            sequences = [
                store.get_sequence(int(s["id"])) or {} for s in store.list_sequences(rover)
            ]
            commands = store.commands(rover, -math.inf, math.inf)
        finally:
            store.close()
        return cls(frames, truth, found, commands, sorted(sequences, key=lambda s: s["id"]))

    def early(self) -> list[str]:
        """Frames and events received earlier than the light allows (``early_rows``)."""
        return early_rows([*self.frames, *((t, r) for t, _k, _x, r in self.events)])
