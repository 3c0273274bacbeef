"""Truth rates derived from the sampled truth: a turn in place and a straight drive."""

import math
from datetime import UTC, datetime

import numpy as np
import pytest

from sim.loop.rover_sim import RoverSim
from sim.rover.drive import initial_state, turn_in_place
from sim.rover.slip import SlipModel
from sim.world.terrain import FlatTerrain

START = datetime(2004, 4, 14, 16, 30, tzinfo=UTC)


def test_turn_in_place_rate_is_the_commanded_rate_about_body_down() -> None:
    flat = FlatTerrain()
    traj, _ = turn_in_place(
        flat, initial_state(flat, 0.0), math.radians(90.0), SlipModel.ideal(flat.soil)
    )
    omega = traj.omega_b_s_in_b()
    steady = omega[2:-2]  # the first and last intervals are shorter (the schedule's ends)
    # Ali et al. 2005: 2.1 deg/s
    np.testing.assert_allclose(steady[:, 2], math.radians(2.1), rtol=1e-9)
    np.testing.assert_allclose(steady[:, :2], 0.0, atol=1e-12)


def test_straight_drive_velocity_is_the_commanded_speed() -> None:
    sim = RoverSim("flat", 0, START, slip=False)
    traj = sim.drive_straight(2.0).truth
    v = traj.v_s()[5:-5]
    np.testing.assert_allclose(v[:, 0], 0.0375, rtol=1e-9)  # Ali et al. 2005: 3.75 cm/s
    np.testing.assert_allclose(v[:, 1:], 0.0, atol=1e-12)


def test_drive_accelerations_integrate_to_rest_and_to_the_displacement() -> None:
    """A drive starts and ends at rest: its accelerations sum to no velocity change and
    integrate twice to its displacement, to half an interval's travel at each end."""
    sim = RoverSim("gusev", 3, START)
    traj = sim.drive_straight(2.0).truth
    a = traj.accel_s_from_rest()
    dt = np.diff(traj.t_s)
    v = np.vstack([np.zeros(3), np.cumsum(a * dt[:, None], axis=0)])
    cruise = np.linalg.norm(v[len(v) // 4 : 3 * len(v) // 4], axis=1)
    np.testing.assert_allclose(cruise, 0.0375, rtol=0.5)  # the drive's speed, over rocks
    assert np.median(cruise) == pytest.approx(0.0375, rel=0.05)
    travel = np.sum(0.5 * (v[1:] + v[:-1]) * dt[:, None], axis=0)
    half_interval_m = 0.0375 * 0.125 / 2.0
    np.testing.assert_allclose(travel, traj.p_s[-1] - traj.p_s[0], atol=2 * half_interval_m)
    assert abs(a[0, 0]) > 0.1  # starting: 3.75 cm/s within the first control cycle or two


def test_the_accelerometers_sense_the_start_of_a_drive() -> None:
    """The IMU senses the rover's own accelerations: on flat ground without slip, the
    first samples of a drive read more forward specific force than the level rest."""
    sim = RoverSim("flat", 0, START, slip=False)
    seg = sim.drive_straight(1.0)
    forward = seg.imu.delta_velocity_b[:, 0] / seg.imu.dt_s
    start, cruise = forward[0], np.median(forward)
    expected = seg.truth.accel_s_from_rest()[0, 0]
    assert start - cruise == pytest.approx(expected, rel=0.05)
