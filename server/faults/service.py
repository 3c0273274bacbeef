"""The conductor's faults on a rover: injected into its session, listed, revealed.

A fault is handed to the rover's session (``RoverSession.faults``, ``sim.faults.plan``),
whose plan holds a lock of its own (the clock thread may be running a command; the plan is
read there only as commands start), and the runtime is asked to checkpoint at its next tick
(``RoverRuntime.session_changed``), so an injected fault survives a restart even with the
clock paused. It takes effect at the first command, or idle step, that starts at or after
its time (``sim.faults.plan``).

Who sees a fault: the conductor role and above always (the list, the truth record's event,
the timeline); everyone else only what the rover reports, until the conductor reveals the
rover's faults (``reveal``): from then on a revealed fault is on the sol timeline for every
reader (``timeline_faults``), for the debrief. Under ``--truth-view everyone`` every reader
sees the truth, so the timeline shows every applied fault to all.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from datetime import UTC, datetime
from typing import Any

from server.errors import InvalidError
from server.runtime import RoverRuntime
from sim.errors import InputError
from sim.faults.records import (
    ScheduledFault,
    fault_from_dict,
)
from sim.world.marsclock import t_s_for_sol_lmst, t_s_to_utc, utc_to_t_s

PAST_TOLERANCE_S = 1.0  # a time this close behind the rover's clock counts as now


class FaultRequestError(InvalidError):
    """A fault request that cannot be: ``loc`` names the body field."""

    def __init__(self, where: tuple[str | int, ...], message: str) -> None:
        super().__init__(message)
        self.loc = ("body", *where)


def fault_time(
    runtime: RoverRuntime,
    at_utc: datetime | None = None,
    at_sol: int | None = None,
    at_lmst_h: float | None = None,
) -> float:
    """When a fault is due, TT s: ``at_utc``, or sol ``at_sol`` at ``at_lmst_h`` (both),
    or (neither) the rover's clock now. A time before the rover's clock is refused."""
    now = runtime.t_s
    if at_utc is not None and (at_sol is not None or at_lmst_h is not None):
        raise FaultRequestError(("at_utc",), "at_utc: give either at_utc or at_sol and at_lmst_h")
    if (at_sol is None) != (at_lmst_h is None):
        missing = "at_lmst_h" if at_lmst_h is None else "at_sol"
        raise FaultRequestError((missing,), f"{missing}: at_sol and at_lmst_h go together")
    if at_utc is not None:
        aware = at_utc if at_utc.tzinfo is not None else at_utc.replace(tzinfo=UTC)
        at, where = utc_to_t_s(aware.astimezone(UTC)), "at_utc"
    elif at_sol is not None and at_lmst_h is not None:
        at, where = t_s_for_sol_lmst(runtime.spec.mission, at_sol, at_lmst_h), "at_sol"
    else:
        return now
    if not math.isfinite(at) or at < now - PAST_TOLERANCE_S:
        raise FaultRequestError(
            (where,), f"{where}: before the rover's clock ({runtime.clock_text()}); "
            "leave the time out for now"
        )  # fmt: skip
    return max(at, now)


def inject(
    runtime: RoverRuntime, kind: str, parameters: Mapping[str, Any], at_t_s: float
) -> ScheduledFault:
    """Schedule the fault ``kind`` with ``parameters`` on ``runtime``'s rover at ``at_t_s``
    (``fault_time``). A parameter that cannot be is a ``FaultRequestError`` naming it (422)."""
    try:
        fault = fault_from_dict({**parameters, "kind": kind})
    except InputError as error:
        where = ("kind",) if error.parameter == "kind" else ("parameters", error.parameter)
        raise FaultRequestError(where, str(error)) from None
    entry = runtime.session.faults.add(fault, at_t_s)
    runtime.session_changed()
    return entry


def reveal(runtime: RoverRuntime) -> int:
    """Reveal every fault of the rover (the debrief); how many were not yet revealed."""
    fresh = runtime.session.faults.reveal()
    runtime.session_changed()
    return fresh


def _when(runtime: RoverRuntime, t_s: float) -> dict[str, Any]:
    return {"t_s": t_s, "utc": t_s_to_utc(t_s).isoformat(), "lmst_h": runtime.lmst_h(t_s),
            "sol": runtime.sol(t_s)}  # fmt: skip


def fault_json(runtime: RoverRuntime, entry: ScheduledFault) -> dict[str, Any]:
    """One fault as the routes and the timeline answer it (``server.api.answers.FaultEntry``)."""
    applied = entry.applied_t_s
    state = "pending" if applied is None else "failed" if entry.error else "applied"
    parameters = {k: v for k, v in entry.fault.as_dict().items() if k != "kind"}
    return {
        "fault_id": entry.fault_id,
        "kind": entry.fault.kind,
        "parameters": parameters,
        "description": entry.fault.describe(),
        "at": _when(runtime, entry.at_t_s),
        "applied": None if applied is None else _when(runtime, applied),
        "state": state,
        "error": entry.error,
        "revealed": entry.revealed,
    }


def listing(runtime: RoverRuntime) -> list[dict[str, Any]]:
    """Every fault of the rover, in the order injected (the conductor's list)."""
    return [fault_json(runtime, e) for e in runtime.session.faults.entries()]


def timeline_faults(
    runtime: RoverRuntime, t0_s: float, t1_s: float, truth: bool
) -> list[dict[str, Any]]:
    """The faults applied between ``t0_s`` and ``t1_s`` that the reader may see: all of
    them in the truth view (``truth``), else only those revealed (module docstring)."""
    return [
        fault_json(runtime, e)
        for e in runtime.session.faults.entries()
        if e.applied_t_s is not None and t0_s <= e.applied_t_s <= t1_s and (truth or e.revealed)
    ]
