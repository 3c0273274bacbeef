"""What the rover reported of a rehearsed sequence's execution, from stored records only.

A campaign's report (``GET .../rehearsals/{id}/report``) places each executed figure in its
predicted distribution (``server.rehearsal.compare``). The execution is found in storage:

- ``executed_sequence``: the campaign's own sequence (``sequence_id``) once it has run
  (``completed`` or ``failed``), else the first sequence of the rover accepted at or after
  the campaign was asked for whose text is the rehearsed text (whitespace at the ends
  aside) and that has run;
- ``executed_steps``: per step of it, in order, its status and reason from the step's
  command report (the ``commands`` table: what the rover reported), and from the stored
  downlink record at the step's end (the last at or before its end time; else the first
  after, within ``FRAME_AFTER_S``) its end time, estimated position and heading, AQF, IMU
  time, position 1σ and predicted HGA margin: each ``None`` where the ground has nothing
  (a step not run, a frame not yet come down across light time);
- ``executed_truth``: for the truth view only, the stored truth records over each step:
  the true position at its end, the largest true tilt during it, the HGA pass's margin.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation
from sqlalchemy import select

from server.storage.schema import commands, sequences
from server.storage.store import Store

RAN = ("completed", "failed")  # a sequence's statuses once it has run
FRAME_BEFORE_S = 120.0  # how far before a step's end its frame is looked for
FRAME_AFTER_S = 2.0  # and after it (frames are recorded at most once a second)


def executed_sequence(store: Store, campaign: Mapping[str, Any]) -> dict[str, Any] | None:
    """The stored sequence whose execution a campaign predicted (module docstring)."""
    own = campaign.get("sequence_id")
    if own is not None:
        found = store.get_sequence(int(own))
        if found is not None and found["status"] in RAN:
            return found
    text = str(campaign["sequence_text"]).strip()
    c = sequences.c
    query = select(c.id).where(c.rover == campaign["rover"], c.status.in_(RAN)).order_by(c.id)
    created = str(campaign["created_t_utc"])
    with store.engine.connect() as conn:
        ids = [int(i) for i in conn.execute(query).scalars()]
    for sequence_id in ids:
        found = store.get_sequence(sequence_id)
        if (found is not None and found["source"].strip() == text
                and str(found["created_at"]) >= created):  # fmt: skip
            return found
    return None


def _step_rows(store: Store, sequence_id: int) -> dict[int, dict[str, Any]]:
    c = commands.c
    query = select(commands).where(c.sequence_id == sequence_id).order_by(c.step_index, c.id)
    with store.engine.connect() as conn:
        return {int(r.step_index): dict(r._mapping) for r in conn.execute(query)
                if r.step_index is not None}  # fmt: skip


def _frame_at(store: Store, rover: str, t_s: float) -> dict[str, Any] | None:
    """The stored downlink record at ``t_s`` (module docstring)."""
    found = store.frames(rover, t_s - FRAME_BEFORE_S, t_s + FRAME_AFTER_S)
    before = [f for f in found if f["t_s"] <= t_s + 1e-6]
    if before:
        return before[-1]
    return found[0] if found else None


def _number(value: Any) -> float | None:
    return float(value) if isinstance(value, int | float) and math.isfinite(value) else None


def heading_rad(q_b_ll: Any) -> float:
    """The heading (from North towards East) of a body attitude ``q_b_ll`` [x, y, z, w]."""
    x_ll = Rotation.from_quat(q_b_ll).inv().apply([1.0, 0.0, 0.0])
    return math.atan2(float(x_ll[1]), float(x_ll[0]))


def tilt_deg(q_b_ll: Any) -> float:
    """The tilt of the body's z axis from the Local-Level Down axis, deg."""
    z_ll = Rotation.from_quat(q_b_ll).inv().apply([0.0, 0.0, 1.0])
    return math.degrees(math.acos(max(-1.0, min(1.0, float(z_ll[2])))))


def executed_steps(store: Store, sequence: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Per step of ``sequence`` (a stored sequence's record), what the rover reported at
    its end (module docstring; the shape ``server.rehearsal.compare`` takes)."""
    rows = _step_rows(store, int(sequence["id"]))
    out: list[dict[str, Any]] = []
    for index, step in enumerate(sequence.get("steps") or []):
        row = rows.get(index)
        entry: dict[str, Any] = {
            "line": int(step["line"]), "status": "not_run", "reason": None, "end_t_s": None,
            "p_mission_est_m": None, "heading_est_rad": None, "aqf": None,
            "imu_integration_s": None, "position_sigma_m": None,
            "hga_margin_predicted_deg": None,
        }  # fmt: skip
        if row is not None:
            entry.update(status=row["status"], reason=row["reason"], end_t_s=row["end_t_s"])
            frame = _frame_at(store, str(sequence["rover"]), float(row["end_t_s"]))
            if frame is not None:
                p = frame["p_mission_est"]
                entry.update(
                    p_mission_est_m=[float(p[0]), float(p[1])],
                    heading_est_rad=heading_rad(frame["q_b_ll_est"]),
                    aqf=frame["aqf"],
                    imu_integration_s=_number(frame["imu_integration_s"]),
                    position_sigma_m=_number(frame.get("position_sigma_m")),
                    hga_margin_predicted_deg=_number(frame.get("hga_margin_predicted_deg")),
                )
        out.append(entry)
    return out


def executed_truth(store: Store, sequence: Mapping[str, Any]) -> list[dict[str, Any]]:
    """Per step that ran, its true figures from the stored truth records (truth view
    only: module docstring)."""
    rows = _step_rows(store, int(sequence["id"]))
    rover = str(sequence["rover"])
    out: list[dict[str, Any]] = []
    for index, step in enumerate(sequence.get("steps") or []):
        row = rows.get(index)
        if row is None:
            continue
        t0, t1 = float(row["start_t_s"]), float(row["end_t_s"])
        truths = store.truths(rover, t0, t1 + FRAME_AFTER_S)
        during = [truths[t] for t in sorted(truths) if t <= t1 + 1e-6] or list(truths.values())
        if not during:
            continue
        last = during[-1]
        margins = [m for m in (_number(t.get("hga_margin_deg")) for t in during) if m is not None]
        out.append({
            "line": int(step["line"]),
            "p_mission_true_m": [float(last["p_mission_true"][0]),
                                 float(last["p_mission_true"][1])],
            "max_tilt_true_deg": float(np.max([tilt_deg(t["q_b_ll_true"]) for t in during])),
            "hga_margin_deg": min(margins) if margins else None,
        })  # fmt: skip
    return out
