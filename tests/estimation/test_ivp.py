"""Onboard IVP (Standish conic approximation) against the DE421 truth and independent solvers."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest
from scipy.optimize import brentq

from estimation import ivp
from sim.world import mars_frames
from sim.world.ephemeris import astrometric_from_mars_j2000_km
from sim.world.marsclock import utc_to_t_s

T_2004 = utc_to_t_s(datetime(2004, 1, 1, tzinfo=UTC))
T_2030 = utc_to_t_s(datetime(2030, 1, 1, tzinfo=UTC))
SITES_DEG = [(-14.57, 175.48), (-1.95, 354.47), (0.0, 0.0), (45.0, 90.0), (-60.0, 270.0)]


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out: np.ndarray = np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))
    return out


@pytest.fixture(scope="module")
def times() -> np.ndarray:
    return np.random.default_rng(2004).uniform(T_2004, T_2030, 250)


@pytest.mark.parametrize(("lat_deg", "lon_east_deg"), SITES_DEG)
def test_ivp_sun_and_earth_agree_with_truth(
    times: np.ndarray, lat_deg: float, lon_east_deg: float
) -> None:
    lat, lon = math.radians(lat_deg), math.radians(lon_east_deg)
    sun_err = _angle_deg(ivp.sun_ll(times, lat, lon), mars_frames.sun_ll_truth(times, lat, lon))
    earth_err = _angle_deg(
        ivp.earth_ll(times, lat, lon), mars_frames.earth_ll_truth(times, lat, lon)
    )
    assert sun_err.max() < 0.05  # measured 0.028 deg
    assert earth_err.max() < 0.1  # measured 0.033 deg
    # The errors are the conic's, not zero: the IVP is a genuinely separate computation.
    assert sun_err.max() > 0.001 and earth_err.max() > 0.001


def test_earth_light_time_and_range(times: np.ndarray) -> None:
    p = ivp.earth_from_mars_j2000_au(times)
    # The light-time equation holds: p = r_EMB(t - |p|/c) - r_Mars(t), to a metre.
    tau_s = np.linalg.norm(p, axis=-1) / ivp.C_AU_S
    r_emb, _ = ivp.heliocentric_state_j2000(ivp.EMB_ELEMENTS, times - tau_s)
    r_mars, _ = ivp.heliocentric_state_j2000(ivp.MARS_ELEMENTS, times)
    assert np.abs(p - (r_emb - r_mars)).max() * ivp.AU_M < 1.0
    # The correction is not negligible: the Earth moves ~30 km/s for 3-22 minutes.
    r_emb_now, _ = ivp.heliocentric_state_j2000(ivp.EMB_ELEMENTS, times)
    shift_km = np.linalg.norm(r_emb_now - r_emb, axis=-1) * ivp.AU_M / 1000.0
    assert shift_km.min() > 4_000.0 and shift_km.max() < 42_000.0
    # Range against DE421 (light time on both sides): measured 71,000 km at most.
    truth_km = np.linalg.norm(astrometric_from_mars_j2000_km("earth", times), axis=-1)
    range_km = np.linalg.norm(p, axis=-1) * ivp.AU_M / 1000.0
    assert np.abs(range_km - truth_km).max() < 100_000.0


def test_onboard_iau_rotation_matches_the_simulators() -> None:
    # Two constructions: axes from pole and node (IVP), product of frame rotations (sim).
    t = np.linspace(-2e9, 2e9, 9)
    assert np.allclose(ivp.R_mf_j2000(t), mars_frames.R_mf_j2000(t), atol=1e-12)
    for lat_deg, lon_deg in SITES_DEG:
        lat, lon = math.radians(lat_deg), math.radians(lon_deg)
        assert np.allclose(ivp.R_ll_mf(lat, lon), mars_frames.R_ll_mf(lat, lon), atol=1e-15)
        assert np.allclose(ivp.mars_rotation_ll(lat), mars_frames.mars_rotation_ll(lat))


def test_kepler_solver_against_brentq() -> None:
    rng = np.random.default_rng(3)
    M = rng.uniform(-math.pi, math.pi, 40)
    e = rng.uniform(0.0, 0.3, 40)
    E = ivp.solve_kepler(M, e)
    for Mi, ei, Ei in zip(M, e, E, strict=True):
        ref = brentq(lambda x, Mi=Mi, ei=ei: x - ei * math.sin(x) - Mi, -4.0, 4.0, xtol=1e-15)
        assert Ei == pytest.approx(ref, abs=1e-12)


def test_conic_orbit_invariants() -> None:
    t = np.linspace(T_2004, T_2030, 50)
    r, v = ivp.heliocentric_state_j2000(ivp.MARS_ELEMENTS, t)
    dist = np.linalg.norm(r, axis=-1)
    # Perihelion 1.381 AU and aphelion 1.666 AU: a (1 -/+ e).
    assert dist.min() > 1.38 and dist.max() < 1.667
    # The velocity is the time derivative of the position (central difference, 60 s).
    r_plus, _ = ivp.heliocentric_state_j2000(ivp.MARS_ELEMENTS, t + 30.0)
    r_minus, _ = ivp.heliocentric_state_j2000(ivp.MARS_ELEMENTS, t - 30.0)
    assert np.allclose((r_plus - r_minus) / 60.0, v, rtol=1e-6)
    # The Earth-Moon barycentre's ecliptic latitude never exceeds its inclination I(T),
    # which drifts from the J2000 ecliptic at -0.013 deg per century.
    r_emb, _ = ivp.heliocentric_state_j2000(ivp.EMB_ELEMENTS, t)
    eps = ivp.OBLIQUITY_J2000_RAD
    z_ecl = -math.sin(eps) * r_emb[:, 1] + math.cos(eps) * r_emb[:, 2]
    lat_deg = np.degrees(np.abs(np.arcsin(z_ecl / np.linalg.norm(r_emb, axis=-1))))
    (i0, i_rate) = ivp.EMB_ELEMENTS[2]
    inclination_deg = np.abs(i0 + i_rate * t / ivp.SECONDS_PER_CENTURY)
    assert np.all(lat_deg <= inclination_deg + 1e-9)
    assert lat_deg.max() > 0.5 * inclination_deg.max()


def test_bad_site_raises_value_error() -> None:
    with pytest.raises(ValueError, match="lat_rad"):
        ivp.sun_ll(0.0, 2.0, 0.0)
    with pytest.raises(ValueError, match="lon_east_rad"):
        ivp.earth_ll(0.0, 0.0, float("inf"))
    with pytest.raises(ValueError, match="t_s"):
        ivp.sun_ll(float("nan"), 0.0, 0.0)
