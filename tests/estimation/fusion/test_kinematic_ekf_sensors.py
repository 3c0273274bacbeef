"""The sensors the kinematic EKF needs (Balaram 2000 secs. 1.3, 2.3): the WASS model and its
inverse, the rocker/bogie sensors, the compliant wheels, and the flight software's copy of
the rover geometry."""

import math
from dataclasses import fields

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.fusion.kinematic.attitude_sensors import (
    R_WASS_B,
    sun_sensor_model,
    sun_vector_from_measurement,
)
from estimation.fusion.kinematic.encoder_rates import interval_rates
from estimation.fusion.kinematic.rover_kinematics import suspension
from estimation.geometry import FLIGHT_GEOMETRY
from sim.rover.compliant_wheels import compliant_wheel_angles
from sim.rover.drive import drive_straight, initial_state
from sim.rover.geometry import MER_GEOMETRY, wheel_kinematics
from sim.rover.slip import SlipModel
from sim.sensors.joint_encoders import JointEncoderParams, JointEncoders
from sim.sensors.sun_sensor import SunSensorParams, WassSunSensor, wass_output
from sim.world.terrain import FlatTerrain


def test_flight_geometry_equals_the_simulated_rover() -> None:
    for f in fields(FLIGHT_GEOMETRY):
        assert getattr(FLIGHT_GEOMETRY, f.name) == getattr(MER_GEOMETRY, f.name), f.name
    rng = np.random.default_rng(0)
    for _ in range(10):
        gamma = rng.normal(0.0, 0.3, 3)
        mine = suspension(gamma)
        sims = wheel_kinematics(MER_GEOMETRY, gamma[0], gamma[1:])
        np.testing.assert_allclose(mine.centre_b, sims.centre_b, atol=1e-15)
        np.testing.assert_allclose(mine.dcentre_dgamma, sims.dcentre_dq, atol=1e-15)
        np.testing.assert_allclose(mine.link_rad, sims.link_rad, atol=1e-15)


def test_sun_sensor_inverse_recovers_the_sun_vector() -> None:
    sensor = WassSunSensor(SunSensorParams(noise_sm=0.0), np.random.default_rng(1))
    sun_s = np.array([-1.0, 1.0, -1.0]) / math.sqrt(3.0)
    q = Rotation.random(200, random_state=2)
    samples = sensor.measure(np.arange(200.0), q.as_quat(), sun_s)
    assert 20 < np.count_nonzero(samples.valid) < 200  # some in view, some not
    for qi, s_m in zip(q[samples.valid], samples.s_m[samples.valid], strict=True):
        sun_b = sun_vector_from_measurement(s_m)
        assert np.linalg.norm(sun_b - qi.inv().apply(sun_s)) < 1e-12  # radians, ~2e-10 deg
    assert np.all(np.isnan(samples.s_m[~samples.valid]))


def test_sun_sensor_field_of_view_and_elevation_formula() -> None:
    # 80 deg off the boresight is the edge of the 160 deg field of view; the paper's
    # elevation π/2 (1 - |s_m|) is the Sun's elevation over the sensor plane.
    off = math.radians(80.0)
    s_wass = np.array([math.sin(off), 0.0, math.cos(off)])
    s_m = wass_output(s_wass)
    assert math.isclose(0.5 * math.pi * (1 - np.linalg.norm(s_m)), math.radians(10.0))
    np.testing.assert_allclose(sun_sensor_model(s_wass), s_m, atol=1e-15)  # sim = flight
    q_sun_below_deck = Rotation.identity().as_quat()[None, :]
    sensor = WassSunSensor(SunSensorParams(), np.random.default_rng(0))
    # Body z is Down; the sensor looks up: a Sun 5 deg below the horizon is not seen.
    sun_low = np.array([math.cos(math.radians(-5.0)), 0.0, math.sin(math.radians(5.0))])
    assert not sensor.measure([0.0], q_sun_below_deck, sun_low).valid[0]
    assert R_WASS_B @ np.array([0.0, 0.0, -1.0]) @ np.array([0.0, 0.0, 1.0]) == 1.0


def test_sun_vector_from_measurement_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="beyond the horizon"):
        sun_vector_from_measurement([0.9, 0.9])
    with pytest.raises(ValueError, match="s_m must be"):
        sun_vector_from_measurement([np.nan, 0.0])


def test_joint_encoders_read_the_suspension_within_their_noise() -> None:
    flat = FlatTerrain()
    traj, _ = drive_straight(flat, initial_state(flat, 0.0), 0.3, SlipModel.ideal(flat.soil))
    params = JointEncoderParams()
    read = JointEncoders(params, np.random.default_rng(3)).read(traj)
    err = np.column_stack([read.rocker_rad - traj.rocker_rad, read.bogie_rad - traj.bogie_rad])
    assert 0.5 * params.noise_rad < np.std(err) < 2.0 * params.noise_rad
    rates = interval_rates(np.column_stack([read.rocker_rad, read.bogie_rad]), read.t_s)
    assert np.sqrt(np.mean(rates**2)) < 0.002  # a flat drive: the joints stay still


def test_compliant_wheels_roll_the_path_on_flat_ground() -> None:
    flat = FlatTerrain()
    traj, _ = drive_straight(flat, initial_state(flat, 0.0), 0.5, SlipModel.ideal(flat.soil))
    wheels = compliant_wheel_angles(flat, traj)
    np.testing.assert_allclose(wheels, traj.wheel_angle_rad, atol=1e-9)  # 0.5 m / r each
