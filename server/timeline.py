"""A sol's timeline for review, from storage: what ran, in which NATE mode and with which
Attitude Quality Flag, what happened, and (in its ``truth`` part, from the truth records) how
good the estimate was; and the faults the conductor injected, for a reader in the truth view
or once revealed (``server.faults``).

Alarms (``server.alarms``) listed are those active at some time of the sol.
Intervals are built from the stored frames (a new interval wherever the mode or flag
changes); times are given as TT seconds, UTC and LMST hours. The summary's distance driven is
the length of the path the rover reports (its estimate, from the downlink); the true
distance is in the ``truth`` part, with the scored events (the truth records' own). For a
reader who may not see the truth (``server.access.truth_view``) there is no ``truth`` part,
and the alarms on truth channels and their events are left out.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from server.access.truth_view import ground_channels, ground_events
from server.alarms import alarm_json
from server.eventlog import rest_event
from server.faults.service import timeline_faults
from server.runtime import RoverRuntime
from server.storage import CommandRecord, Store
from sim.world.marsclock import t_s_for_sol_lmst, t_s_to_utc


def _when(runtime: RoverRuntime, t_s: float) -> dict[str, Any]:
    return {"t_s": t_s, "utc": t_s_to_utc(t_s).isoformat(), "lmst_h": runtime.lmst_h(t_s)}


def command_entry(
    runtime: RoverRuntime, row: dict[str, Any], submitted_by: str | None
) -> dict[str, Any]:
    """One stored command row as the timeline lists it (and as the ``command`` WebSocket
    notice carries it: both are built here, so they cannot differ)."""
    return {
        **row,
        "submitted_by": submitted_by,
        "start": _when(runtime, float(row["start_t_s"])),
        "end": _when(runtime, float(row["end_t_s"])),
    }


def stored_command(
    store: Store, runtime: RoverRuntime, report: CommandRecord
) -> dict[str, Any] | None:
    """The timeline entry of the command a runtime just reported
    (``RuntimeListener.command_reported``), read back from storage once it is written: its
    id, reruns and submitter are the stored ones. ``None`` if it is not stored (the writer
    dropped it)."""
    rover = runtime.spec.name
    start, end = report.start_t_s, report.end_t_s
    rows = [
        c
        for c in store.commands(rover, start, end)
        if c["sequence_id"] == report.sequence_id and c["step_index"] == report.step_index
    ]
    if not rows:
        return None
    row = max(rows, key=lambda c: int(c["id"]))
    seq = row["sequence_id"]
    submitted_by = store.submitters([seq]).get(seq) if seq else None
    return command_entry(runtime, row, submitted_by)


def _intervals(
    runtime: RoverRuntime, frames: list[dict[str, Any]], key: str, end_t_s: float
) -> list[dict[str, Any]]:
    out: list[dict[str, Any]] = []
    for f in frames:
        if not out or out[-1]["value"] != f[key]:
            if out:
                out[-1]["end"] = _when(runtime, float(f["t_s"]))
            out.append({"value": f[key], "start": _when(runtime, float(f["t_s"]))})
    if out:
        out[-1]["end"] = _when(runtime, end_t_s)
    return out


def sol_timeline(
    store: Store, runtime: RoverRuntime, sol: int, truth: bool = True
) -> dict[str, Any] | None:
    """The timeline of ``sol`` for ``runtime``'s rover, or ``None`` without telemetry;
    without the truth unless ``truth`` (module docstring)."""
    rover = runtime.spec.name
    span = store.sol_range(rover, sol)
    if span is None:
        return None
    # The span runs from the sol's first to its last record: a frame, or an event stored
    # outside the frames (the server's start, stamped before the first frame; a restart,
    # stamped at the checkpoint the rover resumed from, before frames stored already).
    mission = runtime.spec.mission
    sol_events = store.events(
        rover, t_s_for_sol_lmst(mission, sol, 0.0), t_s_for_sol_lmst(mission, sol + 1, 0.0)
    )
    events = [e for e in sol_events if runtime.sol(float(e["t_s"])) == sol]
    t0 = min([span[0], *(float(e["t_s"]) for e in events)])
    t1 = max([span[1], *(float(e["t_s"]) for e in events)])
    frames = store.frames(rover, t0, t1)
    truths = list(store.truths(rover, t0, t1).values()) if truth else []
    commands = store.commands(rover, t0, t1)
    alarms = [alarm_json(a) for a in reversed(store.alarms(rover, span=(t0, t1)))]
    if not truth:
        events, alarms = ground_events(events), ground_channels(alarms)
    submitted_by = store.submitters(c["sequence_id"] for c in commands if c["sequence_id"])
    distance = path_length_m(frames, "p_mission_est")  # what the rover reports it drove

    def finite(records: Sequence[Mapping[str, Any]], key: str) -> list[float]:
        return [
            float(f[key])
            for f in records
            if f.get(key) is not None and math.isfinite(float(f[key]))
        ]

    # a margin that does not exist (no attitude to point from) is no figure, not a crash
    margins = finite([f for f in truths if f["earth_up"]], "hga_margin_deg")
    pos_err = finite(truths, "position_error_m")
    att_err = finite(truths, "attitude_error_deg")
    out: dict[str, Any] = {
        "rover": rover,
        "sol": sol,
        "start": _when(runtime, t0),
        "end": _when(runtime, t1),
        "commands": [
            command_entry(runtime, c, submitted_by.get(c["sequence_id"] or 0)) for c in commands
        ],
        "nate_modes": _intervals(runtime, frames, "nate_mode", t1),
        "aqf": _intervals(runtime, frames, "aqf", t1),
        "events": [rest_event(runtime, e) for e in events],
        # alarms raised by the sol's end and not cleared before its start, oldest first
        "alarms": alarms,
        "distance_m": distance,
        "faults": timeline_faults(runtime, t0, t1, truth),
        "summary": {
            "frames": len(frames),
            "commands": len(commands),
            "commands_failed": sum(1 for c in commands if c["status"] != "completed"),
            "distance_m": distance,
            "max_imu_integration_s": max(finite(frames, "imu_integration_s"), default=None),
        },
    }
    if truth:  # the simulator's truth and the scores against it (the truth view's)
        out["truth"] = {
            "distance_m": path_length_m(truths, "p_mission_true"),
            "max_position_error_m": max(pos_err) if pos_err else None,
            "max_attitude_error_deg": max(att_err) if att_err else None,
            "min_hga_margin_deg": min(margins) if margins else None,
            "events": [
                rest_event(runtime, {**e, "t_s": f["t_s"]}) for f in truths for e in f["events"]
            ],
        }
    return out


def path_length_m(records: Sequence[Mapping[str, Any]], key: str) -> float:
    """The horizontal length of the path of the positions ``key`` of ``records``, m."""
    path = np.array([f[key] for f in records], dtype=float)
    if len(path) < 2:
        return 0.0
    return float(np.sum(np.linalg.norm(np.diff(path[:, :2], axis=0), axis=1)))
