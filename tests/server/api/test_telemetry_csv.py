"""Telemetry as CSV: one column per vector component, every row as long as the header, even
for frames stored before a field existed (they get empty cells, not shifted columns)."""

from __future__ import annotations

import csv
import io
from datetime import UTC, datetime

from sequences import commands as cmd
from server.api.telemetry_csv import (
    CSV_COLUMNS,
    CSV_SIDE_ESTIMATORS,
    CSV_SIDE_FIELDS,
    CSV_SIDE_VECTORS,
    CSV_VECTORS,
    frames_csv,
)
from sim.loop.session import RoverSession
from sim.scoring.truth import merged


def test_rows_keep_their_columns_with_old_and_new_frames() -> None:
    session = RoverSession("flat", 3, datetime(2004, 4, 14, 15, 0, tzinfo=UTC))
    session.execute(cmd.DriveStraight(distance_m=0.5))
    new = merged(session.downlinks[-1].as_dict(), session.truths[-1].as_dict())
    old = {k: v for k, v in new.items() if k not in ("sun_ll_true", "steer_deg", "rocker_deg")}
    rows = list(csv.reader(io.StringIO(frames_csv([new, old]))))
    header = rows[0]
    per_side = len(CSV_SIDE_FIELDS) + sum(CSV_SIDE_VECTORS.values())
    side_columns = len(CSV_SIDE_ESTIMATORS) * per_side
    assert len(header) == len(CSV_COLUMNS) + sum(CSV_VECTORS.values()) + side_columns + 1
    assert all(len(row) == len(header) for row in rows[1:])
    by_name = [dict(zip(header, row, strict=True)) for row in rows[1:]]
    assert float(by_name[0]["sun_ll_true_2"]) == new["sun_ll_true"][2]
    assert by_name[1]["sun_ll_true_2"] == "" and by_name[1]["rocker_deg"] == ""
    assert by_name[1]["earth_ll_true_0"] == by_name[0]["earth_ll_true_0"]


def test_the_estimators_beside_sapp_have_their_columns_empty_where_they_did_not_run() -> None:
    session = RoverSession(
        "flat", 3, datetime(2004, 4, 14, 15, 0, tzinfo=UTC), estimators=("sapp", "radio_ekf")
    )
    session.execute(cmd.DriveStraight(distance_m=0.5))
    frame = merged(session.downlinks[-1].as_dict(), session.truths[-1].as_dict())
    rows = list(csv.reader(io.StringIO(frames_csv([frame]))))
    row = dict(zip(rows[0], rows[1], strict=True))
    radio = frame["estimators"]["radio_ekf"]
    assert float(row["radio_ekf_position_error_m"]) == radio["position_error_m"]
    assert float(row["radio_ekf_p_mission_0"]) == radio["p_mission"][0]
    assert row["radio_ekf_attitude_error_deg"] == "" and row["radio_ekf_q_b_ll_3"] == ""
    assert row["kinematic_ekf_position_error_m"] == ""  # it did not run
