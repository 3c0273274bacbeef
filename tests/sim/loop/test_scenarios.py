"""Headless runs: the rover at rest reads Mars turning, ideal wheels go exactly as far as
commanded, and the same seed gives the same run."""

import math
from datetime import UTC, datetime

import numpy as np
from scipy.spatial.transform import Rotation

from estimation.mars_constants import MARS_ROTATION_RATE_RAD_S
from sim.loop.rover_sim import RoverSim
from sim.scenarios.headless import run_scenario
from sim.sensors.imu import Ln200Params

START = datetime(2004, 4, 14, 16, 30, tzinfo=UTC)


def test_rover_at_rest_integrates_its_gyros_to_the_mars_rotation() -> None:
    sim = RoverSim("gusev", 3, START, imu_params=Ln200Params.noise_free())
    sim.rest(3600.0)
    angle_b = sim.totals.gyro_rest_angle_b
    # IAU 2009 rotation rate, 350.892 deg/day: 14.62 deg in an hour, whatever the tilt
    assert math.isclose(np.linalg.norm(angle_b), MARS_ROTATION_RATE_RAD_S * 3600.0, rel_tol=1e-9)
    # and along the spin axis as seen from the tilted body: North-and-up in LL
    axis_ll = Rotation.from_quat(sim.q_ll_b()).apply(angle_b / np.linalg.norm(angle_b))
    lat = math.radians(sim.site.lat_deg)
    np.testing.assert_allclose(axis_ll, [math.cos(lat), 0.0, -math.sin(lat)], atol=1e-9)


def test_noisy_gyros_at_rest_read_mars_rotation_within_the_bias() -> None:
    summary = run_scenario("rest_1h", seed=5)
    gyro = np.array(summary["gyro_rate_b_deg_per_h"])
    mars = np.array(summary["mars_rate_b_deg_per_h"])
    assert math.isclose(np.linalg.norm(mars), 14.6205, abs_tol=1e-3)  # 350.892 deg/day / 24
    # LN-200 class: ~1 deg/h turn-on bias per axis, 0.3 deg/h instability, 0.1 deg/sqrt(h)
    assert np.linalg.norm(gyro - mars) < 5.0 * math.sqrt(3 * (1.0**2 + 0.3**2 + 0.1**2))
    assert summary["cycles_simulated"] == 0 and summary["idle_s_jumped"] == 3600.0


def test_no_slip_straight_drive_on_flat_covers_the_commanded_distance() -> None:
    sim = RoverSim("flat", 0, START, slip=False)
    sim.drive_straight(12.5)
    assert abs(sim.totals.distance_truth_m - 12.5) < 1e-9
    np.testing.assert_allclose(sim.drive_state.p_s[:2], [12.5, 0.0], atol=1e-9)
    # the encoders agree to within one count (34 um of travel)
    assert abs(sim.totals.distance_odometry_m - 12.5) < 40e-6


def test_slip_on_gusev_makes_odometry_overestimate() -> None:
    summary = run_scenario("drive_100m", seed=2, distance_m=6.0)
    assert summary["distance_odometry_m"] > summary["distance_truth_m"]
    assert summary["max_wheel_gap_mm"] <= 2.0
    assert summary["cycles_simulated"] == round(6.0 / 0.0375 * 8)


def test_same_seed_same_run_bit_for_bit() -> None:
    a = run_scenario("turn_360_eq22", seed=4)
    b = run_scenario("turn_360_eq22", seed=4)
    a.pop("wall_s"), b.pop("wall_s")
    assert a == b
    assert abs(a["heading_change_truth_deg"] - 360.0) < 5.0  # a little turn slip, no more
    c = run_scenario("turn_360_eq22", seed=5)
    assert c["final_p_s"] != a["final_p_s"]
