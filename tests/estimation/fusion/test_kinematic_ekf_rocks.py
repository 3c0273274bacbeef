"""The kinematic EKF over rocks, beside SAPP in a session: its contact angles stay on the
wheels' lower halves (the slip constraint's mirror solution), its commands start when the
wheels start rolling, and with the slip noise of rate-controlled wheels it holds its height
over Gusev's rocks (``kinematic_ekf.RATE_CONTROLLED_WHEELS``)."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest

from estimation.fusion.kinematic.ekf import CONTACT_ANGLE_LIMIT_RAD, KinematicEkf
from estimation.fusion.kinematic.slip_constraint import JointRates, slip_constraint
from estimation.sapp.aqf import AttitudeQuality
from sequences import commands as cmd
from sim.loop.rover_sim import RoverSim
from sim.loop.session import RoverSession
from sim.loop.side.kinematic import commanded_rates, starts_with_steering

START = datetime(2004, 4, 14, 15, 0, tzinfo=UTC)
SPEED_M_S = 0.0375
ROLLING_RAD_S = SPEED_M_S / 0.13  # every wheel rolling at the drive speed


def _rolling_straight(psi_rad_s: np.ndarray) -> JointRates:
    zero3, zero6 = np.zeros(3), np.zeros(6)
    return JointRates(zero3, zero3, zero6, zero6, psi_rad_s)


def test_the_slip_constraint_cannot_tell_a_contact_on_top_of_the_wheel() -> None:
    # Driving straight, a contact at ξ + π with the body moving backwards gives the same
    # slip as the true one: the filter must not wander there.
    joints = _rolling_straight(np.full(6, ROLLING_RAD_S))
    xi = np.radians([10.0, -5.0, 30.0, 0.0, 20.0, -40.0])
    v = np.array([SPEED_M_S, 0.0, 0.002])
    ahead = slip_constraint(v, np.zeros(3), xi, joints).slip
    behind = slip_constraint(-v, np.zeros(3), xi + math.pi, joints).slip
    np.testing.assert_allclose(behind, ahead, atol=1e-15)


def test_contact_angles_stay_on_the_lower_half_of_the_wheels() -> None:
    # The left front wheel stands still at a contact angle of 69 deg while the others roll:
    # the linearised update would carry its ξ past 90 deg; the filter holds it at the limit.
    ekf = KinematicEkf([0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0])
    L = ekf.layout
    ekf.X[L.XI.start] = math.radians(69.0)
    ekf.P[L.XI, L.XI] = np.eye(6)  # rad²: a contact angle known to a radian
    ekf.set_command([SPEED_M_S, 0.0, 0.0], [0.0, 0.0, 0.0])
    psi = np.full(6, ROLLING_RAD_S)
    psi[0] = 0.0
    ekf.update_slip(_rolling_straight(psi))
    xi = ekf.estimate().xi_rad
    assert np.all(np.abs(xi) <= CONTACT_ANGLE_LIMIT_RAD)
    assert xi[0] == pytest.approx(CONTACT_ANGLE_LIMIT_RAD)  # pushed up to the limit


def test_commands_start_when_the_wheels_start_rolling() -> None:
    # An arc steers first; the straight after it straightens the wheels first; the next
    # straight starts at once (sim.loop.rover_sim). The command must start with the rolling.
    sim = RoverSim("flat", 3, START, slip=False)
    legs = [
        ("arc", (5.0, math.radians(10.0)), sim.drive_arc(5.0, math.radians(10.0))),
        ("straight", (0.3,), sim.drive_straight(0.3)),
        ("straight", (0.3,), sim.drive_straight(0.3)),
    ]
    assert [starts_with_steering(k, seg.encoders.steer_rad) for k, _, seg in legs] == [
        True,
        True,
        False,
    ]
    for kind, args, seg in legs:
        t = seg.truth.t_s
        steering = starts_with_steering(kind, seg.encoders.steer_rad)
        v_c, _ = commanded_rates(kind, args, t, steering)
        truth_speed = np.linalg.norm(np.diff(seg.truth.p_s, axis=0), axis=1) / np.diff(t)
        np.testing.assert_allclose(v_c[:, 0], truth_speed, atol=1e-6)  # m/s
    with pytest.raises(ValueError, match="kind"):
        commanded_rates("hop", (1.0,), np.array([0.0, 1.0]))


def test_over_gusev_rocks_the_filter_holds_its_height() -> None:
    # Seed 5 drives over several rocks in its first 5 m. The rover's wheels turn at their
    # commanded rates and skid on the rocks; with the compliant wheels' 1 mm/s the filter
    # explained each skid by tilting its contact angles and was 0.4 m too low after 5 m.
    session = RoverSession("gusev", 5, START, slip=False, estimators=("sapp", "kinematic_ekf"))
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    session.execute(cmd.DriveStraight(distance_m=5.0))
    last, truth = session.downlinks[-1], session.truths[-1]
    error = np.subtract(last.estimators["kinematic_ekf"]["p_mission"], truth.p_mission_true)
    assert np.linalg.norm(error) < 0.15  # m
