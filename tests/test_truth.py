"""Truth rates derived from the sampled truth: a turn in place and a straight drive."""

import math
from datetime import UTC, datetime

import numpy as np

from sim.drive import initial_state, turn_in_place
from sim.rover_sim import RoverSim
from sim.slip import SlipModel
from sim.terrain import FlatTerrain

START = datetime(2004, 4, 14, 16, 30, tzinfo=UTC)


def test_turn_in_place_rate_is_the_commanded_rate_about_body_down() -> None:
    flat = FlatTerrain()
    traj, _ = turn_in_place(
        flat, initial_state(flat, 0.0), math.radians(90.0), SlipModel.ideal(flat.soil)
    )
    omega = traj.omega_b_s_in_b()
    steady = omega[2:-2]  # the first and last intervals are shorter (the schedule's ends)
    np.testing.assert_allclose(steady[:, 2], math.radians(2.1), rtol=1e-9)  # seed 000: 2.1 deg/s
    np.testing.assert_allclose(steady[:, :2], 0.0, atol=1e-12)


def test_straight_drive_velocity_is_the_commanded_speed() -> None:
    sim = RoverSim("flat", 0, START, slip=False)
    traj = sim.drive_straight(2.0).truth
    v = traj.v_s()[5:-5]
    np.testing.assert_allclose(v[:, 0], 0.0375, rtol=1e-9)  # seed 000: 3.75 cm/s
    np.testing.assert_allclose(v[:, 1:], 0.0, atol=1e-12)
