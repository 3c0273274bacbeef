"""The ground rebuilds the rover's keep-out zones and mobility fault from the events that came
down, and validation predicts with them: checked against the rover's own onboard table."""

from __future__ import annotations

import dataclasses
from datetime import UTC, datetime

from sequences import commands as cmd
from sequences.validate import validate
from server.validation.context import site_context
from server.validation.reported import ReportedState
from sim.loop.session import RoverSession

START = datetime(2004, 4, 14, 16, 30, tzinfo=UTC)


def test_the_events_rebuild_the_onboard_table_and_fault() -> None:
    s = RoverSession("gusev", 5, START)
    s.execute(cmd.KeepoutAdd(zone="rock", x_m=2.5, y_m=0.0, radius_m=0.3))
    s.execute(cmd.KeepoutAdd(zone="dune", polygon_m="-3,-1 -2,-1 -2.5,1"))
    s.execute(cmd.KeepoutAdd(zone="gone", x_m=9.0, y_m=9.0, radius_m=1.0))
    s.execute(cmd.KeepoutClear(zone="gone"))
    halted = s.execute(cmd.DriveStraight(distance_m=4.0))
    assert halted.status == "halted"
    ground = ReportedState()
    ground.note(e for d, _ in s.take_frames() for e in d["events"])
    onboard = s.loop.protection
    assert ground.zones == onboard.zones
    assert onboard.fault is not None and ground.mobility_fault == onboard.fault.reason
    s.execute(cmd.ClearMobilityFault())
    ground.note(e for d, _ in s.take_frames() for e in d["events"])
    assert ground.mobility_fault is None


def test_validation_warns_with_the_reported_zones_and_fault() -> None:
    s = RoverSession("gusev", 5, START)
    s.execute(cmd.KeepoutAdd(zone="rock", x_m=2.5, y_m=0.0, radius_m=0.3))
    s.execute(cmd.DriveStraight(distance_m=4.0))  # halted at the rock
    frames = s.take_frames()
    ground = ReportedState()
    ground.note(e for d, _ in frames for e in d["events"])
    last = frames[-1][0]
    ctx = dataclasses.replace(
        site_context("spirit", 0.0, 3.06, last["t_s"]),
        p_s_est=(last["p_s_est"][0], last["p_s_est"][1]),
        heading_rad=0.0,
        keepout_zones=tuple(ground.zones.values()),
        mobility_fault=ground.mobility_fault,
        position_sigma_m=float(last["position_sigma_m"] or 0.0),
    )
    result = validate("DRIVE_STRAIGHT distance_m=2\n", ctx)
    assert [
        w.code for w in result.warnings if w.code in ("drive-after-halt", "keepout-crossing")
    ] == [
        "drive-after-halt",
        "keepout-crossing",
    ]
