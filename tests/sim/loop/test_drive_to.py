"""DRIVE_TO: the rover turns towards a goal in the current Site and drives to it by its own
estimate, so with perfect sensors and no slip it arrives; a goal too far is refused with
nothing changed; the command parses from sequence text."""

import math

import numpy as np
import pytest

from estimation.sapp.aqf import AttitudeQuality
from sequences import commands as cmd
from sequences.language import parse
from sim.loop.session import RoverSession
from sim.sensors.imu import Ln200Params
from tests.sim.loop.test_session_helpers import START


@pytest.mark.parametrize(("x_m", "y_m"), [(3.0, -4.0), (-2.0, 0.5), (0.0, 6.0)])
def test_drive_to_arrives_with_perfect_sensors_and_no_slip(x_m: float, y_m: float) -> None:
    session = RoverSession(
        "flat", 4, START, imu_params=Ln200Params.noise_free(), slip=False, yaw_rad=0.7
    )
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    report = session.execute(cmd.DriveTo(x_m, y_m))
    assert report.status == "completed"
    frame = session.truths[-1]
    assert np.hypot(frame.p_s_true[0] - x_m, frame.p_s_true[1] - y_m) < 0.02
    assert report.details["distance_m"] == pytest.approx(math.hypot(x_m, y_m), abs=1e-9)


def test_a_goal_beyond_100_m_is_refused_and_nothing_moves() -> None:
    session = RoverSession("flat", 4, START)
    before = (session.sim.t_s, session.nate.p_s.tolist(), session.nate.q_b_ll.tolist())
    report = session.execute(cmd.DriveTo(80.0, 80.0))
    assert report.status == "refused" and "113.14 m" in (report.reason or "")
    assert (session.sim.t_s, session.nate.p_s.tolist(), session.nate.q_b_ll.tolist()) == before


def test_drive_to_parses_and_validates() -> None:
    (step,) = parse("DRIVE_TO x_m=3 y_m=-4.5\n").steps
    assert step.command == cmd.DriveTo(3.0, -4.5)
    with pytest.raises(ValueError, match="y_m"):
        cmd.DriveTo(0.0, 2000.0)
