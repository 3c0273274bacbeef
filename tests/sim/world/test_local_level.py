"""The Site-to-Local-Level rotation against the Mars-fixed geometry of sim.world.mars_frames."""

import math

import numpy as np
from scipy.spatial.transform import Rotation

from estimation.mars_constants import MARS_EQUATORIAL_RADIUS_M
from sim.world.local_level import R_ll_s, q_ll_b_from_site
from sim.world.mars_frames import R_ll_mf, site_mf_m

LAT = math.radians(-14.57)
LON = math.radians(175.48)


def test_identity_at_the_site_origin() -> None:
    np.testing.assert_allclose(R_ll_s([0.0, 0.0, 0.0], LAT, LON), np.eye(3), atol=1e-15)


def test_matches_ll_of_the_ellipsoid_point_reached() -> None:
    # Walk 100 m North-East on the ellipsoid in Mars-fixed coordinates, find the point's
    # latitude/longitude independently (from the normal direction), compare LL frames.
    p_s = np.array([70.0, 70.0, 0.0])
    R_mf_ll0 = R_ll_mf(LAT, LON).T
    p_mf = site_mf_m(LAT, LON) + R_mf_ll0 @ p_s
    # nearest ellipsoid normal: iterate the planetographic latitude of p_mf
    lon = math.atan2(p_mf[1], p_mf[0])
    lat = LAT
    b2_a2 = (3_376_200.0 / MARS_EQUATORIAL_RADIUS_M) ** 2
    for _ in range(5):
        lat = math.atan2(p_mf[2], b2_a2 * math.hypot(p_mf[0], p_mf[1]))
    expected = R_ll_mf(lat, lon) @ R_mf_ll0
    got = R_ll_s(p_s, LAT, LON)
    angle = Rotation.from_matrix(got @ expected.T).magnitude()
    assert angle < 1e-8  # rad; the frame turned by ~100 m / R = 2.9e-5 rad
    assert Rotation.from_matrix(got).magnitude() > 2.5e-5


def test_attitude_conversion_composes() -> None:
    q_s_b = Rotation.from_euler("z", 30, degrees=True).as_quat()[None, :]
    p_s = np.array([[0.0, 0.0, 0.0]])
    np.testing.assert_allclose(q_ll_b_from_site(q_s_b, p_s, LAT, LON), q_s_b, atol=1e-15)
