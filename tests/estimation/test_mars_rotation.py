"""The Mars rotation vector in Local-Level, checked independently of its closed form.

``sim.world.mars_frames.mars_rotation_ll`` and ``estimation.ivp.mars_rotation_ll`` write
``Ω (cos φ, 0, -sin φ)``; here the rate is differentiated numerically from the IAU 2009
rotation of the Mars-fixed frame, with its sign, so the gyros' truth is not circular.
"""

import math
from datetime import UTC, datetime

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation import ivp
from sim.world.mars_frames import R_ll_mf, R_mf_j2000, mars_rotation_ll
from sim.world.marsclock import utc_to_t_s


@pytest.mark.parametrize(("lat_deg", "lon_east_deg"), [(-14.57, 175.48), (-1.95, 354.47), (60, 30)])
def test_rotation_vector_from_differentiated_iau_frames(
    lat_deg: float, lon_east_deg: float
) -> None:
    t = utc_to_t_s(datetime(2004, 4, 14, 12, tzinfo=UTC))
    dt = 10.0
    lat, lon = math.radians(lat_deg), math.radians(lon_east_deg)
    # R_ll_j2000 at t and t + dt: the LL frame turns with Mars relative to inertial space
    R_ll_mf_site = R_ll_mf(lat, lon)
    R0 = R_ll_mf_site @ R_mf_j2000(t)
    R1 = R_ll_mf_site @ R_mf_j2000(t + dt)
    # R_j2000_ll(t+dt) = R_j2000_ll(t) exp([w_ll]x dt): w_ll is the rate of LL in LL axes
    omega_ll = Rotation.from_matrix(R0 @ R1.T).as_rotvec() / dt
    np.testing.assert_allclose(mars_rotation_ll(lat), omega_ll, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(ivp.mars_rotation_ll(lat), omega_ll, rtol=1e-6, atol=1e-12)
    # in the south the spin axis points below the horizon's North (Down component > 0)
    assert (omega_ll[2] > 0) == (lat_deg < 0)
