"""Stored run outcomes back into ``sim.rehearsal.outcome.RunOutcome``.

A campaign's outcomes are stored as JSON (``server.storage.rehearsals``), where a NaN
(``hga_margin_deg`` of a step that is no HGA pass) is ``null`` and a tuple a list:
``outcomes_from_dicts`` undoes both, so a report made from stored outcomes is the one made
from the campaign's own.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import fields
from typing import Any

from sim.rehearsal.outcome import RunOutcome, StepOutcome

_FLOATS = {f.name for f in fields(StepOutcome) if f.type in ("float", float)}


def _pairs(value: Any) -> tuple[tuple[float, float], ...]:
    return tuple((float(p[0]), float(p[1])) for p in value or ())


def step_from_dict(step: Mapping[str, Any]) -> StepOutcome:
    """A ``StepOutcome`` from its JSON form (``RunOutcome.as_dict``)."""
    values = dict(step)
    for name in _FLOATS:
        if name in values:
            values[name] = math.nan if values[name] is None else float(values[name])
    for name in ("p_mission_true_m", "p_mission_est_m"):
        p = values[name]
        values[name] = (float(p[0]), float(p[1]))
    values["keepouts_entered"] = tuple(values.get("keepouts_entered") or ())
    values["path_true_m"] = _pairs(values.get("path_true_m"))
    return StepOutcome(**values)


def outcomes_from_dicts(found: Iterable[Mapping[str, Any]]) -> list[RunOutcome]:
    """``RunOutcome``s from their JSON forms, in the order given."""
    return [
        RunOutcome(
            run_index=int(r["run_index"]),
            seed=int(r["seed"]),
            steps=tuple(step_from_dict(s) for s in r["steps"]),
            wall_s=float(r.get("wall_s") or 0.0),
            worker=str(r.get("worker") or ""),
            extra=dict(r.get("extra") or {}),
        )
        for r in found
    ]
