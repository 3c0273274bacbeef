"""Telemetry as CSV: one column per vector component, every row as long as the header, even
for frames stored before a field existed (they get empty cells, not shifted columns)."""

from __future__ import annotations

import csv
import io
from datetime import UTC, datetime

from sequences import commands as cmd
from server.app import CSV_COLUMNS, CSV_VECTORS, _csv
from sim.session import RoverSession


def test_rows_keep_their_columns_with_old_and_new_frames() -> None:
    session = RoverSession("flat", 3, datetime(2004, 4, 14, 15, 0, tzinfo=UTC))
    session.execute(cmd.DriveStraight(distance_m=0.5))
    new = session.frames[-1].as_dict()
    old = {k: v for k, v in new.items() if k not in ("sun_ll_true", "steer_deg", "rocker_deg")}
    rows = list(csv.reader(io.StringIO(_csv([new, old]))))
    header = rows[0]
    assert len(header) == len(CSV_COLUMNS) + sum(CSV_VECTORS.values()) + 1
    assert all(len(row) == len(header) for row in rows[1:])
    by_name = [dict(zip(header, row, strict=True)) for row in rows[1:]]
    assert float(by_name[0]["sun_ll_true_2"]) == new["sun_ll_true"][2]
    assert by_name[1]["sun_ll_true_2"] == "" and by_name[1]["rocker_deg"] == ""
    assert by_name[1]["earth_ll_true_0"] == by_name[0]["earth_ll_true_0"]
