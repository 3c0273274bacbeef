"""The flight shadow mask (estimation.vo.shadow_mask) against the renderer's own shadow (a
ray cast in numba, sim.sensors.navcam.trace, an independent implementation), and its hook
in the VO front (off by default)."""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.vo.odometry import VisualOdometry
from estimation.vo.shadow_mask import in_rover_shadow, rays_meet_rover
from sim.loop.rover_sim import RoverSim
from sim.loop.vo_drive import VO_MAST_AZ_RAD, VO_MAST_EL_RAD, VO_RIG

DAY = datetime(2004, 3, 1, tzinfo=UTC)


def _low_sun_time() -> datetime:
    """The first moment of the day, in 10 min steps, with the Sun 25-35 deg high."""
    for k in range(144):
        utc = DAY + timedelta(minutes=10 * k)
        sun = RoverSim("flat", 3, utc).sun_ll()
        if 25.0 <= math.degrees(math.asin(-float(sun[2]))) <= 35.0:
            return utc
    raise AssertionError("no low sun that day")


def _sim_facing_away_from_the_sun() -> tuple[RoverSim, np.ndarray]:
    utc = _low_sun_time()
    sun = RoverSim("flat", 3, utc).sun_ll()
    yaw = math.atan2(float(sun[1]), float(sun[0])) + math.pi + math.radians(15.0)
    return RoverSim("flat", 3, utc, yaw_rad=yaw), sun


def test_the_mask_agrees_with_the_rendered_shadow() -> None:
    sim, sun_s = _sim_facing_away_from_the_sun()
    assert 10.0 < math.degrees(math.asin(-sun_s[2])) < 60.0
    kwargs = {"rig": VO_RIG, "noise": False}
    lit = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, **kwargs)
    shaded = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rover_shadow=True, **kwargs)
    dark = shaded.left < 0.9 * lit.left  # the renderer's rover shadow
    assert 0.05 < dark.mean() < 0.6
    # each pixel's ground point, from its depth, in the body frame
    cam = VO_RIG.camera
    v, u = np.mgrid[0 : cam.height_px, 0 : cam.width_px]
    ground = np.isfinite(lit.depth_left_m)
    rays = cam.unproject(u[ground], v[ground])
    p_cam = rays * (lit.depth_left_m[ground] / rays[:, 2])[:, None]
    left_b, _ = VO_RIG.eye_centres_b(lit.az_rad, lit.el_rad)
    p_b = left_b + p_cam @ VO_RIG.R_b_cam(lit.az_rad, lit.el_rad).T
    sun_b = Rotation.from_quat(lit.q_s_b).inv().apply(sun_s)
    predicted = in_rover_shadow(p_b, sun_b)
    agree = np.mean(predicted == dark[ground])
    assert agree > 0.98, agree
    # grown by a margin, the mask covers the whole rendered shadow and its edge
    assert np.all(in_rover_shadow(p_b, sun_b, 0.1)[dark[ground]] | ~predicted[dark[ground]])
    assert in_rover_shadow(p_b, sun_b, 0.1)[dark[ground]].mean() > 0.995


def test_rays_meet_the_parts_they_cross() -> None:
    # from 2 m ahead at deck height, towards the body: the deck; upwards from beside it: nothing
    start = np.array([[2.0, 0.0, -0.37], [2.0, 2.0, 0.3]])
    hit = rays_meet_rover(start, np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]]))
    assert hit.tolist() == [True, False]
    # the same ray stopped short of the deck (its front edge is 1.2 m away)
    assert not rays_meet_rover(start[:1], np.array([[-1.0, 0.0, 0.0]]), [1.1])[0]
    # a wheel (the left front, at x 0.7, y -0.6), seen from its side
    assert rays_meet_rover([[0.7, -2.0, 0.17]], [[0.0, 1.0, 0.0]], [1.35])[0]
    with pytest.raises(ValueError, match="sun_b"):
        in_rover_shadow([[1.0, 0.0, 0.3]], [0.0, 0.0, -2.0])


def test_the_vo_hook_drops_the_shadowed_features_and_is_off_by_default() -> None:
    sim, sun_s = _sim_facing_away_from_the_sun()
    pair = sim.navcam_pair(VO_MAST_AZ_RAD, VO_MAST_EL_RAD, rig=VO_RIG, rover_shadow=True)
    R_s_b = Rotation.from_quat(pair.q_s_b).as_matrix()
    kw = {"R_b0_b1_predicted": np.eye(3), "p_b1_b0_predicted": np.zeros(3), "R_s_b0": R_s_b,
          "mast_az_rad": VO_MAST_AZ_RAD, "mast_el_rad": VO_MAST_EL_RAD}  # fmt: skip
    plain, default = VisualOdometry(VO_RIG), VisualOdometry(VO_RIG)
    a = plain.step(pair.left, pair.right, **kw)
    b = default.step(pair.left, pair.right, sun_b=None, **kw)
    assert np.array_equal(a.features.features_uv_px, b.features.features_uv_px)
    masked = VisualOdometry(VO_RIG)
    sun_b = R_s_b.T @ sun_s
    m = masked.step(pair.left, pair.right, sun_b=sun_b, **kw)
    assert 0 < m.n_features < a.n_features
    kept = masked.state()["previous"]["p_b"]
    assert not in_rover_shadow(kept, sun_b, 0.1).any()
    dropped = plain.state()["previous"]["p_b"]
    assert in_rover_shadow(dropped, sun_b, 0.1).sum() == a.n_features - m.n_features
