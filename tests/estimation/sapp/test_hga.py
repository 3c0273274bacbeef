"""HGA pointing: the onboard command from the estimate and IVP, judged against the truth."""

import math
from datetime import UTC, datetime

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation import ivp
from estimation.sapp.hga_pointing import hga_boresight_b, point_hga, point_hga_many
from sim.rover.hga import hga_errors_deg, hga_pointing_truth
from sim.world.mars_frames import earth_ll_truth, elevation_rad
from sim.world.marsclock import utc_to_t_s

LAT, LON = math.radians(-14.57), math.radians(175.48)


def _earth_up_time() -> float:
    t0 = utc_to_t_s(datetime(2004, 4, 14, tzinfo=UTC))
    t = t0 + np.arange(0, 88775, 600.0)
    el = elevation_rad(earth_ll_truth(t, LAT, LON))
    return float(t[np.argmax(el)])  # Earth near its highest that sol


def test_perfect_attitude_points_within_the_ivp_error() -> None:
    t = _earth_up_time()
    q_b_ll = Rotation.from_euler("ZYX", [40.0, 5.0, -3.0], degrees=True).inv().as_quat()
    command = point_hga(q_b_ll, ivp.earth_ll(t, LAT, LON))
    assert command.earth_above_horizon and command.within_gimbal
    result = hga_pointing_truth(command, q_b_ll, earth_ll_truth(t, LAT, LON))
    assert result.error_deg < 0.05  # the IVP's conic against DE421 (tests/estimation/test_ivp.py)
    assert result.margin_deg == pytest.approx(2.0 - result.error_deg)


@pytest.mark.parametrize("yaw_error_deg", [0.5, 1.5, 3.0])
def test_heading_error_costs_its_cosine_of_elevation(yaw_error_deg: float) -> None:
    # A heading error δ about the LL vertical moves a direction at elevation e by
    # 2 asin(cos e sin(δ/2)) (spherical geometry): the classic HGA budget relation.
    t = _earth_up_time()
    earth = earth_ll_truth(t, LAT, LON)
    q_b_ll_true = Rotation.from_euler("ZYX", [10.0, 2.0, 1.0], degrees=True).inv().as_quat()
    yaw_error = Rotation.from_euler("z", yaw_error_deg, degrees=True)
    q_b_ll_est = (Rotation.from_quat(q_b_ll_true) * yaw_error).as_quat()  # error in LL
    result = hga_pointing_truth(point_hga(q_b_ll_est, earth), q_b_ll_true, earth)
    e = elevation_rad(earth)
    expected = math.degrees(2 * math.asin(math.cos(e) * math.sin(math.radians(yaw_error_deg) / 2)))
    assert result.error_deg == pytest.approx(expected, abs=1e-9)
    assert (result.margin_deg < 0) == (expected > 2.0)


def test_earth_below_the_horizon_is_reported() -> None:
    earth_ll = np.array([1.0, 0.0, 0.5]) / math.sqrt(1.25)  # Down component > 0: below
    command = point_hga([0, 0, 0, 1.0], earth_ll)
    assert not command.earth_above_horizon
    assert not command.within_gimbal  # below the deck of a level rover too
    # the dish stops at the deck: it misses Earth by Earth's depression, atan(0.5)
    result = hga_pointing_truth(command, [0, 0, 0, 1.0], earth_ll)
    assert result.error_deg == pytest.approx(math.degrees(math.atan(0.5)), abs=1e-9)


def test_gimbal_angles_point_where_the_command_says() -> None:
    rng = np.random.default_rng(11)
    for _ in range(50):
        q = Rotation.random(random_state=rng).as_quat()
        earth = rng.normal(size=3)
        command = point_hga(q, earth / np.linalg.norm(earth))
        if command.within_gimbal:
            aimed = hga_boresight_b(command.az_rad, command.el_rad)
            np.testing.assert_allclose(aimed, command.boresight_b, atol=1e-12)
            expected_b = Rotation.from_quat(q).apply(earth / np.linalg.norm(earth))
            np.testing.assert_allclose(aimed, expected_b, atol=1e-12)


def test_bad_arguments_name_the_parameter() -> None:
    with pytest.raises(ValueError, match="earth_ll"):
        point_hga([0, 0, 0, 1.0], [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="q_b_ll_est"):
        point_hga([0, 0, 0, np.nan], [1.0, 0.0, 0.0])


def test_many_pointings_at_once_are_the_pointings_one_by_one() -> None:
    """``point_hga_many`` and ``hga_errors_deg`` (the frames' path) against ``point_hga``
    and ``hga_pointing_truth``, including Earth below the deck (the gimbal at its stop)."""
    rng = np.random.default_rng(16)
    q_est = Rotation.random(300, random_state=3).as_quat()
    q_true = Rotation.from_rotvec(rng.normal(0.0, 0.02, (300, 3))) * Rotation.from_quat(q_est)
    earth = rng.normal(size=(300, 3))
    az, el, boresight_b = point_hga_many(q_est, earth)
    errors = hga_errors_deg(
        az, el, q_true.as_quat(), earth / np.linalg.norm(earth, axis=1)[:, None]
    )
    for k in range(300):
        one = point_hga(q_est[k], earth[k])
        assert (az[k], el[k]) == pytest.approx((one.az_rad, one.el_rad), abs=1e-12)
        assert np.allclose(boresight_b[k], one.boresight_b, rtol=0.0, atol=1e-12)
        truth = hga_pointing_truth(one, q_true[k].as_quat(), earth[k] / np.linalg.norm(earth[k]))
        assert errors[k] == pytest.approx(truth.error_deg, abs=1e-9)
    assert (el == 0.0).any() and (el > 0.0).any()
