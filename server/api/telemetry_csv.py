"""Telemetry frames as CSV, the columns read from the two records' models (``Downlink`` and
``Truth``).

One column per scalar field (numbers, names, flags), then one per component of each vector
field (``q_b_ll_est_0`` ...; lengths from ``server.channels``), then each estimator that can
run beside SAPP with its figures (``<name>_position_error_m`` ...), then the frame's events in
one cell. The columns that existed when a frame was one record keep the places they had
then (``COLUMNS_BEFORE_THE_SPLIT``: scripts read the columns by position too); a field added
to either record since is a new column after them, without an edit here. A figure a frame
lacks (NaN, an estimator that did not run, a field frames stored by an older version do not
have) is an empty cell, so every row is as long as the header. For a reader who may not see
the simulator's truth (``server.access.truth_view``) the truth's columns are absent, not
empty: the truth record's fields and the side estimators' errors.
"""

from __future__ import annotations

import csv
import io
import typing
from dataclasses import fields
from typing import Any

from server.access.truth_view import TRUTH_FIGURES
from server.channels import SIDE_FIELDS, SIDE_TRUTH, vector_length
from sim.loop.downlink import ESTIMATORS, Downlink
from sim.scoring.truth import Truth

# The frame's fields, in order, when it was one record (before issue 21's split).
COLUMNS_BEFORE_THE_SPLIT = (
    "t_s", "sol", "lmst_h", "nate_mode", "aqf", "q_b_ll_est", "q_b_ll_true", "p_s_est",
    "p_s_true", "site_index", "p_mission_est", "p_mission_true", "imu_integration_s",
    "gyro_counter_s", "tilt_est_deg", "tilt_accel_deg", "hga_error_deg", "hga_margin_deg",
    "hga_margin_predicted_deg", "vo_failures_in_row", "earth_up", "attitude_error_deg",
    "position_error_m", "command", "rocker_deg", "bogie_deg", "steer_deg", "sun_ll_true",
    "earth_ll_true", "hga_boresight_ll_true",
)  # fmt: skip


def _columns() -> tuple[tuple[str, ...], dict[str, int]]:
    """The scalar columns and the vector fields with their lengths, from the models."""
    kinds: dict[str, Any] = {}
    for record in (Downlink, Truth):
        hints = typing.get_type_hints(record)
        for f in fields(record):
            kinds.setdefault(f.name, hints[f.name])
    order = [n for n in COLUMNS_BEFORE_THE_SPLIT if n in kinds]
    order += [n for n in kinds if n not in order]
    scalars: list[str] = []
    vectors: dict[str, int] = {}
    for name in order:
        hint = kinds[name]
        if hint in (float, int, str, bool):
            scalars.append(name)
        elif typing.get_origin(hint) is list and typing.get_args(hint) == (float,):
            vectors[name] = vector_length(name)
        # events (the last cell) and estimators (the side columns) are not columns
    return tuple(scalars), vectors


CSV_COLUMNS, CSV_VECTORS = _columns()
# Each estimator that can run beside SAPP (sim.loop.side.kinematic) has its columns in every
# CSV, empty where it did not run: columns never depend on the rover's configuration.
CSV_SIDE_ESTIMATORS = tuple(e for e in ESTIMATORS if e != "sapp")
CSV_SIDE_FIELDS = tuple(k for k, n in SIDE_FIELDS.items() if n is None)
CSV_SIDE_VECTORS = {k: n for k, n in SIDE_FIELDS.items() if n is not None}


def _side_cells(f: dict[str, Any], side_fields: tuple[str, ...]) -> list[Any]:
    cells: list[Any] = []
    for name in CSV_SIDE_ESTIMATORS:
        side = (f.get("estimators") or {}).get(name) or {}
        cells += [side.get(c) for c in side_fields]
        for v, n in CSV_SIDE_VECTORS.items():
            values = list(side.get(v) or [])
            cells += values + [None] * (n - len(values))
    return cells


def frames_csv(frames: list[dict[str, Any]], truth: bool = True) -> str:
    """Frames as CSV (module docstring); without the truth's columns unless ``truth``."""
    columns, vectors, side_fields = CSV_COLUMNS, CSV_VECTORS, CSV_SIDE_FIELDS
    if not truth:
        columns = tuple(c for c in columns if c not in TRUTH_FIGURES)
        vectors = {v: n for v, n in vectors.items() if v not in TRUTH_FIGURES}
        side_fields = tuple(c for c in side_fields if c not in SIDE_TRUTH)
    out = io.StringIO()
    writer = csv.writer(out)
    header = list(columns)
    for v, n in vectors.items():
        header += [f"{v}_{i}" for i in range(n)]
    for name in CSV_SIDE_ESTIMATORS:
        header += [f"{name}_{c}" for c in side_fields]
        for v, n in CSV_SIDE_VECTORS.items():
            header += [f"{name}_{v}_{i}" for i in range(n)]
    header.append("events")
    writer.writerow(header)
    for f in frames:
        row = [f.get(c) for c in columns]
        for v, n in vectors.items():
            values = list(f.get(v) or [])
            row += values + [None] * (n - len(values))
        row += _side_cells(f, side_fields)
        row.append("; ".join(e["text"] for e in f.get("events", [])))
        writer.writerow(row)
    return out.getvalue()
