"""Balaram's kinematic EKF beside SAPP in a rover session (the fusion issue, item 3): it
starts from SAPP's estimate at the first drive, runs on the drive's own sensors, and its
pose and errors are in every frame after that."""

from __future__ import annotations

import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient

from estimation.sapp.aqf import AttitudeQuality
from sequences import commands as cmd
from server.app import ServerConfig, create_app, data_dir_url
from sim.errors import InputError
from sim.loop.session import RoverSession

START = datetime(2004, 4, 14, 15, 0, tzinfo=UTC)


def test_the_ekf_runs_beside_sapp_and_reports_its_errors() -> None:
    session = RoverSession("flat", 5, START, slip=False, estimators=("sapp", "kinematic_ekf"))
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    session.execute(cmd.Wait(duration_s=60.0))
    assert session.downlinks[-1].estimators == {}  # it starts at the first drive
    session.execute(cmd.DriveStraight(distance_m=3.0))
    during = [f for f in session.downlinks if f.estimators]
    assert len(during) > 50  # every frame of the drive
    last = session.downlinks[-1].estimators["kinematic_ekf"]
    assert set(last) == {"p_mission", "q_b_ll"}  # its pose: what runs beside SAPP reports
    last = {**last, **session.truths[-1].estimators["kinematic_ekf"]}  # and its score
    assert set(last) == {"p_mission", "q_b_ll", "position_error_m", "attitude_error_deg"}
    # flat ground, no slip, a 3-axis gyro: the filter stays within 1 % and a few tenths
    assert last["position_error_m"] < 0.03
    assert last["attitude_error_deg"] < 0.3
    assert last["p_mission"][0] == pytest.approx(3.0, abs=0.05)
    session.execute(cmd.Wait(duration_s=60.0))  # at rest it keeps its estimate
    assert session.downlinks[-1].estimators["kinematic_ekf"]["p_mission"] == last["p_mission"]


def test_only_known_estimators_and_always_sapp() -> None:
    with pytest.raises(InputError, match="estimators"):
        RoverSession("flat", 5, START, estimators=("sapp", "radio"))
    with pytest.raises(InputError, match="estimators"):
        RoverSession("flat", 5, START, estimators=("kinematic_ekf",))


def test_the_server_runs_them_and_serves_their_frames(tmp_path: Path) -> None:
    config = ServerConfig(
        database_url=data_dir_url(tmp_path),
        operator_token="side-estimators-token",
        estimators=("sapp", "kinematic_ekf"),
    )
    auth = {"Authorization": "Bearer side-estimators-token"}
    with TestClient(create_app(config)) as client:
        body = {"command": "DRIVE_STRAIGHT", "args": {"distance_m": 1.0}}
        assert client.post("/api/rovers/spirit/commands", json=body, headers=auth).is_success
        client.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=auth)
        deadline = time.monotonic() + 60.0
        frame: dict[str, Any] = {}
        while time.monotonic() < deadline:
            frame = client.get("/api/rovers/spirit/state").json()["frame"] or {}
            if frame.get("estimators") and frame["command"] == "":
                break
            time.sleep(0.2)
        side = frame["estimators"]["kinematic_ekf"]
        assert side["p_mission"][0] == pytest.approx(1.0, abs=0.3)
        stored = client.get("/api/rovers/spirit/telemetry").json()
        assert any(f.get("estimators") for f in stored)  # stored with the frames
