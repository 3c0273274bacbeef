"""Telemetry frames as CSV, the columns read from the frame's model (``TelemetryFrame``).

One column per scalar field (numbers, names, flags) in the model's order, then one per
component of each vector field (``q_b_ll_est_0`` ...; lengths from ``server.channels``),
then each estimator that can run beside SAPP with its figures (``<name>_position_error_m``
...), then the frame's events in one cell. A field added to ``TelemetryFrame`` is a new
column without an edit here. A figure a frame lacks (NaN, an estimator that did not run, a
field frames stored by an older version do not have) is an empty cell, so every row is as
long as the header.
"""

from __future__ import annotations

import csv
import io
import typing
from dataclasses import fields
from typing import Any

from server.channels import SIDE_FIELDS, vector_length
from sim.loop.side.kinematic import ESTIMATORS
from sim.loop.telemetry import TelemetryFrame

# Two fields added after the CSV had users keep the place they were given then, beside
# their kin (scripts read the columns by position too): each is placed after the named one.
PLACED_AFTER = {
    "hga_margin_predicted_deg": "hga_margin_deg",
    "vo_failures_in_row": "hga_margin_predicted_deg",
}


def _columns() -> tuple[tuple[str, ...], dict[str, int]]:
    """The scalar columns and the vector fields with their lengths, from the model."""
    hints = typing.get_type_hints(TelemetryFrame)
    scalars: list[str] = []
    vectors: dict[str, int] = {}
    for f in fields(TelemetryFrame):
        hint = hints[f.name]
        if hint in (float, int, str, bool):
            scalars.append(f.name)
        elif typing.get_origin(hint) is list and typing.get_args(hint) == (float,):
            vectors[f.name] = vector_length(f.name)
        # events (the last cell) and estimators (the side columns) are not columns
    for name, after in PLACED_AFTER.items():
        scalars.remove(name)
        scalars.insert(scalars.index(after) + 1, name)
    return tuple(scalars), vectors


CSV_COLUMNS, CSV_VECTORS = _columns()
# Each estimator that can run beside SAPP (sim.loop.side.kinematic) has its columns in every
# CSV, empty where it did not run: columns never depend on the rover's configuration.
CSV_SIDE_ESTIMATORS = tuple(e for e in ESTIMATORS if e != "sapp")
CSV_SIDE_FIELDS = tuple(k for k, n in SIDE_FIELDS.items() if n is None)
CSV_SIDE_VECTORS = {k: n for k, n in SIDE_FIELDS.items() if n is not None}


def _side_cells(f: dict[str, Any]) -> list[Any]:
    cells: list[Any] = []
    for name in CSV_SIDE_ESTIMATORS:
        side = (f.get("estimators") or {}).get(name) or {}
        cells += [side.get(c) for c in CSV_SIDE_FIELDS]
        for v, n in CSV_SIDE_VECTORS.items():
            values = list(side.get(v) or [])
            cells += values + [None] * (n - len(values))
    return cells


def frames_csv(frames: list[dict[str, Any]]) -> str:
    """Frames as CSV (module docstring)."""
    out = io.StringIO()
    writer = csv.writer(out)
    header = list(CSV_COLUMNS)
    for v, n in CSV_VECTORS.items():
        header += [f"{v}_{i}" for i in range(n)]
    for name in CSV_SIDE_ESTIMATORS:
        header += [f"{name}_{c}" for c in CSV_SIDE_FIELDS]
        for v, n in CSV_SIDE_VECTORS.items():
            header += [f"{name}_{v}_{i}" for i in range(n)]
    header.append("events")
    writer.writerow(header)
    for f in frames:
        row = [f.get(c) for c in CSV_COLUMNS]
        for v, n in CSV_VECTORS.items():
            values = list(f.get(v) or [])
            row += values + [None] * (n - len(values))
        row += _side_cells(f)
        row.append("; ".join(e["text"] for e in f.get("events", [])))
        writer.writerow(row)
    return out.getvalue()
