"""SAPP gyro propagation (Ali et al. 2005 sec. 2.4) on the simulator's IMU: Mars' rotation is
subtracted, so a rover at rest keeps its attitude, and a turn follows the truth."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.ivp import mars_rotation_ll
from estimation.sapp.gyro_propagation import propagate_gyro
from sim.rover.drive import initial_state, turn_in_place
from sim.rover.slip import SlipModel
from sim.sensors.imu import Ln200Imu, Ln200Params
from sim.world.terrain import Eq22Terrain

LAT = math.radians(-14.57)
OMEGA_LL = mars_rotation_ll(LAT)


def _angle_between(q_a: np.ndarray, q_b: np.ndarray) -> float:
    return float((Rotation.from_quat(q_a).inv() * Rotation.from_quat(q_b)).magnitude())


def test_rover_at_rest_keeps_its_attitude_for_an_hour() -> None:
    q_ll_b = Rotation.from_euler("ZYX", [37.0, 4.0, -6.0], degrees=True).as_quat()
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    n = 8 * 3600
    t = np.arange(n + 1) * 0.125
    samples = imu.measure(t, np.tile(q_ll_b, (n + 1, 1)), OMEGA_LL)
    # the gyros saw Mars turn 14.6 deg in that hour ...
    assert np.linalg.norm(samples.delta_angle_b.sum(axis=0)) == pytest.approx(0.2552, abs=1e-3)
    q_b_ll = Rotation.from_quat(q_ll_b).inv().as_quat()
    q = propagate_gyro(q_b_ll, samples.delta_angle_b, samples.dt_s, OMEGA_LL)
    # ... and the propagated estimate did not move
    assert _angle_between(q[-1], q_b_ll) < 1e-9


def test_without_the_subtraction_the_estimate_would_drift_by_mars_rotation() -> None:
    q_b_ll = np.array([0.0, 0.0, 0.0, 1.0])
    d_theta = np.tile(Rotation.from_quat(q_b_ll).apply(OMEGA_LL * 0.125), (800, 1))
    kept = propagate_gyro(q_b_ll, d_theta, 0.125, OMEGA_LL)
    drifted = propagate_gyro(q_b_ll, d_theta, 0.125, np.zeros(3))
    assert _angle_between(kept[-1], q_b_ll) < 1e-12
    assert _angle_between(drifted[-1], q_b_ll) == pytest.approx(np.linalg.norm(OMEGA_LL) * 100.0)


def test_turn_in_place_on_eq22_follows_the_truth() -> None:
    terrain = Eq22Terrain()
    start = initial_state(terrain, 0.0)
    traj, _ = turn_in_place(terrain, start, math.radians(90.0), SlipModel.ideal(terrain.soil))
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    samples = imu.measure(traj.t_s, traj.q_s_b, OMEGA_LL)  # Site = LL at the origin
    q_b_ll_true = Rotation.from_quat(traj.q_s_b).inv().as_quat()
    q = propagate_gyro(q_b_ll_true[0], samples.delta_angle_b, samples.dt_s, OMEGA_LL)
    errors = [_angle_between(a, b) for a, b in zip(q, q_b_ll_true, strict=True)]
    # The paper subtracts Mars' rotation as a vector (sec. 2.4.1): per step that misses the
    # commutator of the two rotations, ½ |ω_perp dt| |Δψ|, with ω_perp = Ω cos(lat) the part
    # of Mars' rate across the turn axis (Down). Over the turn it adds up to ½ ω_perp dt ψ.
    predicted = 0.5 * np.linalg.norm(OMEGA_LL) * math.cos(LAT) * 0.125 * math.radians(90.0)
    assert errors[-1] == pytest.approx(predicted, rel=0.05)  # 6.7 urad, 0.0004 deg
    assert _angle_between(q_b_ll_true[0], q_b_ll_true[-1]) > math.radians(89.0)


def test_bad_arguments_name_the_parameter() -> None:
    with pytest.raises(ValueError, match="delta_angle_b"):
        propagate_gyro([0, 0, 0, 1.0], np.zeros((3, 2)), 0.125, OMEGA_LL)
    with pytest.raises(ValueError, match="dt_s"):
        propagate_gyro([0, 0, 0, 1.0], np.zeros((3, 3)), 0.0, OMEGA_LL)
    with pytest.raises(ValueError, match="q_b_ll"):
        propagate_gyro([0, 0, 0, 0.0], np.zeros((3, 3)), 0.125, OMEGA_LL)


def test_a_wrong_estimate_at_rest_drifts_at_its_share_of_mars_rotation() -> None:
    # Subtracting Mars' rotation with a heading error δ leaves ω_perp 2 sin(δ/2) of rate,
    # with ω_perp = Ω cos(lat) the part of the spin across the error axis (Down): 0.25 deg
    # an hour per degree of heading error at Gusev (sec. 2.4.1's subtraction, by geometry).
    q_ll_b = Rotation.from_euler("ZYX", [37.0, 4.0, -6.0], degrees=True).as_quat()
    imu = Ln200Imu(Ln200Params.noise_free(), np.random.default_rng(0))
    n = 8 * 3600
    samples = imu.measure(np.arange(n + 1) * 0.125, np.tile(q_ll_b, (n + 1, 1)), OMEGA_LL)
    q_b_ll_true = Rotation.from_quat(q_ll_b).inv()
    error = Rotation.from_euler("z", 1.0, degrees=True)  # 1 deg about LL Down
    q_b_ll_est = (q_b_ll_true * error).as_quat()
    q = propagate_gyro(q_b_ll_est, samples.delta_angle_b, samples.dt_s, OMEGA_LL)
    drift = _angle_between(q[-1], q_b_ll_est)
    predicted = np.linalg.norm(OMEGA_LL) * math.cos(LAT) * 2 * math.sin(math.radians(0.5)) * 3600
    assert drift == pytest.approx(predicted, rel=0.02)
