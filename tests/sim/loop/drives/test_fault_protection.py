"""Mobility fault protection in the loop: a real drive halted by each onboard check, the
world stopped where the flight software decided, mobility disabled until the ground clears
the fault, and the onboard tables kept by a checkpoint."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest

from estimation.protection.drive_time import lmst_h
from sequences import commands as cmd
from sim.loop.session import RoverSession

START = datetime(2004, 4, 14, 16, 30, tzinfo=UTC)


def _true_xy(session: RoverSession) -> np.ndarray:
    return session.sim.drive_state.p_s[:2].copy()


def test_a_keepout_zone_halts_the_drive_before_the_grown_disc_touches_it() -> None:
    s = RoverSession("gusev", 5, START)
    s.execute(cmd.KeepoutAdd(zone="rock", x_m=2.5, y_m=0.0, radius_m=0.3))
    report = s.execute(cmd.DriveStraight(distance_m=4.0))
    assert report.status == "halted", report.reason
    halt = report.details["halt"]
    assert halt["check"] == "keepout" and "rock" in report.reason
    # halted where the estimate's disc touched the zone: the estimate and the truth short of it
    clearance = 2.5 - 0.3 - float(s.nate.p_s[0])
    assert halt["values"]["margin_m"] == pytest.approx(2 * halt["values"]["sigma_m"])
    assert 0.0 < clearance <= halt["values"]["margin_m"] + 0.01  # one cycle's travel
    assert float(np.hypot(*(_true_xy(s) - [2.5, 0.0]))) > 0.3
    assert any(e.kind == "mobility" and e.severity == "error" for e in report.events)
    # mobility stays disabled until the ground clears it
    refused = s.execute(cmd.TurnInPlace(angle_deg=90.0))
    assert refused.status == "refused" and "CLEAR_MOBILITY_FAULT" in str(refused.reason)
    assert s.execute(cmd.ClearMobilityFault()).status == "completed"
    assert s.execute(cmd.TurnInPlace(angle_deg=180.0)).status == "completed"
    back = s.execute(cmd.DriveStraight(distance_m=1.0))  # away from the zone
    assert back.status == "completed", back.reason


def test_a_drive_past_its_timeout_halts_at_the_cycle() -> None:
    s = RoverSession("gusev", 6, START)
    t0 = s.sim.t_s
    report = s.execute(cmd.DriveStraight(distance_m=3.0, timeout_s=20.0))
    assert report.status == "halted" and report.details["halt"]["check"] == "timeout"
    assert s.sim.t_s - t0 == pytest.approx(20.125, abs=0.2)  # the first cycle past 20 s
    assert report.details["distance_truth_m"] < 1.0  # 3.75 cm/s for 20 s


def test_a_tilt_limit_under_the_terrains_slopes_halts_on_the_accelerometers() -> None:
    s = RoverSession("gusev", 7, START)
    assert s.execute(cmd.SetParam(param="mobility.tilt_limit_rad", value=0.002)).status == (
        "completed"
    )
    report = s.execute(cmd.DriveStraight(distance_m=2.0))
    assert report.status == "halted" and report.details["halt"]["check"] == "tilt"
    values = report.details["halt"]["values"]
    assert max(abs(values["roll_rad"]), abs(values["pitch_rad"])) > 0.002


def test_a_time_of_day_limit_already_reached_halts_at_once() -> None:
    s = RoverSession("gusev", 8, START)
    now = lmst_h(s.nate.t_s, s.sim.lon_east_rad)
    limit = (now + 0.01) % 24.0  # 36 s from now
    report = s.execute(cmd.DriveStraight(distance_m=3.0, lmst_limit_h=limit))
    assert report.status == "halted" and report.details["halt"]["check"] == "lmst"
    assert report.details["distance_truth_m"] < 3.0


def test_the_onboard_tables_survive_a_checkpoint() -> None:
    s = RoverSession("gusev", 9, START)
    s.execute(cmd.KeepoutAdd(zone="dune", polygon_m="3,-1 5,-1 5,1 3,1"))
    s.execute(cmd.SetParam(param="mobility.slip_limit", value=0.3))
    s.execute(cmd.DriveStraight(distance_m=4.0))  # halts at the dune
    state = s.state()
    again = RoverSession("gusev", 9, START)
    again.load_state(state)
    p = again.loop.protection
    assert p.fault is not None and p.fault.check == "keepout"
    assert set(p.zones) == {"dune"} and p.limits.slip_limit == 0.3
    assert p.uncertainty.sigma_m == s.loop.protection.uncertainty.sigma_m > 0.0
    assert again.execute(cmd.KeepoutClear(zone="all")).status == "completed"
    assert again.loop.protection.zones == {}


def test_a_vo_drive_halts_on_its_slip_check() -> None:
    """Gusev's soil slips a few percent; a limit of 0 % and a check after every step stop
    the drive at its first check, with the slip VO measured."""
    s = RoverSession("gusev", 5, START)
    s.execute(cmd.SetParam(param="mobility.slip_check_m", value=0.5))
    report = s.execute(cmd.DriveStraight(distance_m=1.5, vo=True, slip_limit_pct=0.0))
    assert report.status == "halted", report.reason
    halt = report.details["halt"]
    assert halt["check"] == "slip" and halt["values"]["slip"] > 0.0
    assert report.details["vo_updates"] == 1
    assert math.isclose(halt["values"]["slip_limit"], 0.0)
