"""The event log of a rover: every stored event, filtered and paged for the console.

Events are stored with their kind and severity (``estimation.events``; those stored before
they had them are kind ``unknown``, severity ``info``). Over REST each event is
``{"t_s", "utc", "lmst_h", "sol", "text", "kind", "severity"}``, as in the sol timeline.

The filters (``EventFilter``): a sol or a range of sols (turned into the times the sols
span at the rover's site, so events stored without a sol are found too), kinds, a set of
severities or a minimum one, and a text the event contains (any case). The log is newest
first; a page is ``limit`` events from ``offset``, and ``before_t_s`` starts it at a time
(continue with ``offset``: several events often share one ``t_s``, so a page boundary at a
time could split them).

For a reader who may not see the simulator's truth (``server.access.truth_view``) the events
of alarms on truth channels are left out, of the page and of its ``total``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from estimation.events import KINDS, SEVERITIES
from server.access.truth_view import ground_events
from server.errors import InvalidError
from server.runtime import RoverRuntime
from server.storage import LEGACY_KIND, Store
from sim.world.marsclock import t_s_for_sol_lmst, t_s_to_utc

LOG_KINDS: tuple[str, ...] = (*KINDS, LEGACY_KIND)  # what the kind filter accepts
MAX_LIMIT = 1000


class FilterError(InvalidError):
    """A filter that cannot be met: ``param`` names the query parameter."""

    def __init__(self, param: str, message: str) -> None:
        super().__init__(f"{param}: {message}")
        self.param = param
        self.loc = ("query", param)


@dataclass(frozen=True)
class EventFilter:
    """What the operator asked for (module docstring); ``check`` says what is wrong."""

    sol: int | None = None
    sol_from: int | None = None
    sol_to: int | None = None
    kinds: tuple[str, ...] = ()
    severities: tuple[str, ...] = ()
    min_severity: str | None = None
    text: str | None = None
    before_t_s: float | None = None
    limit: int = 200
    offset: int = 0

    def check(self) -> None:
        """``FilterError`` naming the first parameter that is wrong."""
        if self.sol is not None and (self.sol_from is not None or self.sol_to is not None):
            raise FilterError("sol", "give sol, or sol_from and/or sol_to, not both")
        if self.sol_from is not None and self.sol_to is not None and self.sol_from > self.sol_to:
            raise FilterError("sol_from", f"sol_from {self.sol_from} is after sol_to {self.sol_to}")
        for kind in self.kinds:
            if kind not in LOG_KINDS:
                raise FilterError("kind", f"{kind!r} is not one of {', '.join(LOG_KINDS)}")
        wrong = [s for s in self.severities if s not in SEVERITIES]
        if wrong:
            raise FilterError("severity", f"{wrong[0]!r} is not one of {', '.join(SEVERITIES)}")
        if self.min_severity is not None and self.min_severity not in SEVERITIES:
            raise FilterError(
                "min_severity", f"{self.min_severity!r} is not one of {', '.join(SEVERITIES)}"
            )
        if self.text is not None and "\x00" in self.text:  # PostgreSQL refuses NUL in text
            raise FilterError("text", "must not contain a NUL character")
        if self.before_t_s is not None and not math.isfinite(self.before_t_s):
            raise FilterError("before_t_s", "must be finite")

    def severity_set(self) -> tuple[str, ...]:
        """The severities wanted: of ``severities`` (all if none), those at or above
        ``min_severity``; empty if the two exclude each other."""
        floor = 0 if self.min_severity is None else SEVERITIES.index(self.min_severity)
        return tuple(s for s in SEVERITIES[floor:] if not self.severities or s in self.severities)


def rest_event(runtime: RoverRuntime, event: dict[str, Any]) -> dict[str, Any]:
    """A stored event (``Store.events``) with its times at ``runtime``'s site."""
    t_s = float(event["t_s"])
    return {
        "t_s": t_s,
        "utc": t_s_to_utc(t_s).isoformat(),
        "lmst_h": runtime.lmst_h(t_s),
        "sol": runtime.sol(t_s),
        "text": event["text"],
        "kind": event["kind"],
        "severity": event["severity"],
    }


def event_log(
    store: Store, runtime: RoverRuntime, flt: EventFilter, truth: bool = True
) -> dict[str, Any]:
    """The page of the rover's event log ``flt`` asks for: ``{"rover", "kinds", "total",
    "offset", "limit", "events"}``, ``total`` counting every event that matches and
    ``kinds`` the kinds the filter accepts; without the truth's events unless ``truth``."""
    flt.check()
    mission = runtime.spec.mission
    first = flt.sol if flt.sol is not None else flt.sol_from
    last = flt.sol if flt.sol is not None else flt.sol_to
    t_from = -math.inf if first is None else t_s_for_sol_lmst(mission, first, 0.0)
    before = math.inf if flt.before_t_s is None else flt.before_t_s
    if last is not None:
        before = min(before, t_s_for_sol_lmst(mission, last + 1, 0.0))
    severities = flt.severity_set()
    page: dict[str, Any] = {
        "rover": runtime.spec.name,
        "kinds": list(LOG_KINDS),  # what the kind filter accepts, for the console's picker
        "offset": flt.offset,
        "limit": flt.limit,
    }
    if not severities:  # e.g. severity=info with min_severity=error: nothing can match
        return {**page, "total": 0, "events": []}
    rows, total = store.event_log(
        runtime.spec.name,
        t_from,
        math.inf,
        kinds=flt.kinds,
        severities=severities,
        text_contains=flt.text,
        before_t_s=None if math.isinf(before) else before,
        # without the truth: every match read, so that the page and its total skip the
        # truth's events (the storage cannot tell them apart; a log is thousands of events)
        limit=flt.limit if truth else None,
        offset=flt.offset if truth else 0,
    )
    if not truth:
        kept = ground_events(rows)
        rows, total = kept[flt.offset : flt.offset + flt.limit], len(kept)
    return {**page, "total": total, "events": [rest_event(runtime, e) for e in rows]}
