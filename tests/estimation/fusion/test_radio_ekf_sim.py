"""Jiang, Li et al. 2014's simulator side: the relay orbiter against Kepler, the onboard beacon
against the orbiter, landmark pixels against the flight model, and a short filter run."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from estimation.fusion.radio import models as rm
from estimation.fusion.radio.beacon import OrbitingBeacon
from estimation.mars_constants import MARS_GM_M3_S2
from sim.sensors.landmarks import (
    NAVCAM_FOCAL_PX,
    NAVCAM_OFFSET_B_M,
    LandmarkMap,
    build_landmark_map,
    choose_pair,
    navcam_pixels,
)
from sim.sensors.orbiter import KeplerOrbit, RelayOrbiter
from sim.world.mars_frames import R_ll_mf, site_mf_m
from sim.world.sites import make_terrain

EPOCH_T_S = 131_000_000.0  # March 2004
LAT, LON = math.radians(-1.95), math.radians(354.47)


def test_orbiter_obeys_keplers_laws() -> None:
    orbit = KeplerOrbit(eccentricity=0.05, mean_anomaly_rad=0.3, epoch_t_s=EPOCH_T_S)
    orbiter = RelayOrbiter(orbit)
    a = orbit.semi_major_axis_m
    assert orbit.period_s == pytest.approx(2 * math.pi * math.sqrt(a**3 / MARS_GM_M3_S2))
    assert 110.0 < KeplerOrbit().period_s / 60.0 < 125.0  # Odyssey: ~118 min
    t = EPOCH_T_S + np.linspace(0.0, orbit.period_s, 97)
    r, v = orbiter.state_mci(t)
    radius = np.linalg.norm(r, axis=-1)
    energy = 0.5 * np.sum(v * v, axis=-1) - MARS_GM_M3_S2 / radius  # vis-viva
    np.testing.assert_allclose(energy, -MARS_GM_M3_S2 / (2 * a), rtol=1e-10)
    h = np.linalg.norm(np.cross(r, v), axis=-1)  # second law: constant areal velocity
    np.testing.assert_allclose(h, math.sqrt(MARS_GM_M3_S2 * a * (1 - 0.05**2)), rtol=1e-10)
    np.testing.assert_allclose(r[-1], r[0], atol=1e-3)  # back after one period
    assert radius.min() == pytest.approx(a * 0.95, rel=1e-4)
    normal = np.cross(r[0], v[0]) / h[0]
    assert math.degrees(math.acos(normal[2])) == pytest.approx(93.2, abs=1e-9)


def test_onboard_two_body_propagation_follows_the_keplerian_truth() -> None:
    orbiter = RelayOrbiter(KeplerOrbit(epoch_t_s=EPOCH_T_S))
    r0, v0 = orbiter.state_j2000(EPOCH_T_S + 50.0)
    beacon = OrbitingBeacon(r0, v0, EPOCH_T_S + 50.0)
    for dt in (1.0, 300.0, 1000.0):
        t = EPOCH_T_S + 50.0 + dt
        truth = orbiter.position_mf_m(t)
        assert np.linalg.norm(beacon.position_mf_m(t) - truth) < 0.01  # RK4, 10 s steps
    with pytest.raises(ValueError, match="t_s"):
        beacon.advance_to(EPOCH_T_S)


def test_ranges_are_masked_below_the_horizon_and_noisy_above() -> None:
    orbiter = RelayOrbiter(KeplerOrbit(epoch_t_s=EPOCH_T_S))
    site = site_mf_m(LAT, LON)
    peaks = orbiter.passes(EPOCH_T_S, 86_400.0, site, LAT, LON, 30.0)
    assert peaks.size >= 1
    t = peaks[0] + np.linspace(-1500.0, 1500.0, 301)
    rover = np.tile(site, (t.size, 1))
    rng = np.random.default_rng(1)
    measured, visible = orbiter.ranges(t, rover, LAT, LON, 1.0, rng)
    elev = orbiter.elevation_deg(t, site, LAT, LON)
    np.testing.assert_array_equal(visible, elev >= 10.0)
    assert visible[150] and not visible[0]
    assert np.all(np.isnan(measured[~visible]))
    truth = np.linalg.norm(orbiter.position_mf_m(t) - rover, axis=-1)
    residual = measured[visible] - truth[visible]
    assert 0.7 < float(np.std(residual)) < 1.3
    assert float(truth[150]) < 0.5 * 3_000_000.0


def test_landmark_map_errors_have_the_maps_resolution() -> None:
    terrain = make_terrain("meridiani", 3)
    rng = np.random.default_rng(2)
    landmarks = build_landmark_map(terrain, 10.0, rng, extent_m=200.0, spacing_m=40.0)
    assert landmarks.true_s_m.shape == (100, 3)
    err = landmarks.map_s_m - landmarks.true_s_m
    assert 8.0 < float(np.std(err)) < 12.0
    fine = build_landmark_map(terrain, 0.25, rng, extent_m=40.0)
    assert 0.2 < float(np.std(fine.map_s_m - fine.true_s_m)) < 0.3
    # the landmarks lie on the ground (meridiani is within a metre of the datum)
    assert float(np.max(np.abs(fine.true_s_m[:, 2]))) < 1.5


def test_navcam_pixels_agree_with_the_flight_model() -> None:
    """The simulator's camera (Site frame) and the filter's eqs. 10-11 (Mars-fixed, LL)
    see the same noise-free pixels for an exact map: the frames are consistent."""
    rng = np.random.default_rng(4)
    p_s = np.array([12.0, -7.0, 0.3])
    yaw, pitch, roll = 0.8, 0.05, -0.03
    R_s_b = rm.R_ll_b_from_euler(roll, pitch, yaw)  # Site axes = LL at the origin
    landmarks_s = np.array([[30.0, 10.0, 0.5], [0.0, 15.0, -0.2], [40.0, -30.0, 0.1]])
    pair = choose_pair(p_s, yaw, landmarks_s, rng)
    assert pair is not None
    ids, pans = pair
    pixels = navcam_pixels(p_s, R_s_b, pans, landmarks_s[ids], 0.0, rng)
    exact = LandmarkMap(landmarks_s, landmarks_s, 0.25).map_mf_m(LAT, LON)
    M, N, _, _ = rm.radii_of_curvature_m(LAT)
    x = np.array([LAT + p_s[0] / M, LON + p_s[1] / (N * math.cos(LAT)), 0.0, 0.0])
    offset_ll = R_s_b @ np.asarray(NAVCAM_OFFSET_B_M)
    for i, j in enumerate(ids):
        R_cam_ll = rm.R_cam_b(float(pans[i])) @ R_s_b.T
        predicted, _, _, depth = rm.landmark_pixels(
            x, -p_s[2], exact[j], R_cam_ll, offset_ll, NAVCAM_FOCAL_PX
        )
        assert depth > 0.0
        np.testing.assert_allclose(predicted, pixels[i], atol=0.05)  # 0.05 px
    # the pans centre the landmarks: within half the 45° field
    assert np.all(np.abs(pixels[:, 0]) < 0.5 * NAVCAM_FOCAL_PX)


def test_site_frame_and_geodetic_positions_agree() -> None:
    p_s = np.array([30.0, -40.0, -2.0])
    r_site = site_mf_m(LAT, LON) + p_s @ R_ll_mf(LAT, LON)
    M, N, _, _ = rm.radii_of_curvature_m(LAT)
    r_geo = rm.position_mf_m(LAT + p_s[0] / M, LON + p_s[1] / (N * math.cos(LAT)), 2.0)
    assert np.linalg.norm(r_site - r_geo) < 0.005  # the tangent plane's sag over 50 m


@pytest.mark.parametrize(
    ("call", "name"),
    [
        (lambda: KeplerOrbit(eccentricity=0.95), "eccentricity"),
        (lambda: KeplerOrbit(semi_major_axis_m=1e6), "semi_major_axis_m"),
        (lambda: KeplerOrbit(inclination_rad=float("nan")), "inclination_rad"),
        (
            lambda: build_landmark_map(make_terrain("flat", 0), 0.0, np.random.default_rng(0)),
            "resolution_m",
        ),
        (
            lambda: RelayOrbiter().ranges(
                np.zeros(2), np.zeros((3, 3)), LAT, LON, 1.0, np.random.default_rng(0)
            ),
            "rover_mf_m",
        ),
        (lambda: OrbitingBeacon((1.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0), "r_j2000_m"),
    ],
)
def test_bad_inputs_raise_value_error_naming_them(call: Callable[[], object], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        call()


def test_short_filter_run_tracks_the_rover() -> None:
    """100 s of case 4 on one drive: the estimate converges from its 10 m start."""
    from bench.fusion_radio import ORBIT_EPOCH, TUNINGS, run_case
    from sim.scenarios.radio import build_scenario, drive_starts_t_s
    from sim.world.marsclock import utc_to_t_s

    orbiter = RelayOrbiter(KeplerOrbit(epoch_t_s=utc_to_t_s(ORBIT_EPOCH)))
    scenario = build_scenario(1, orbiter, float(drive_starts_t_s(orbiter, 2)[1]))
    short = scenario.__class__(
        **{
            **scenario.__dict__,
            "t_s": scenario.t_s[:101],
            "p_s": scenario.p_s[:101],
            "v_ne": scenario.v_ne[:101],
            "R_s_b": scenario.R_s_b[:101],
            "euler_rad": scenario.euler_rad[:101],
        }
    )
    out = run_case(short, 4, TUNINGS["scenario_q"])
    assert len(out["err_m"]) == 100
    assert max(out["err_m"][-20:]) < 1.0
    assert float(np.mean(out["nees"][-50:])) < 20.0
