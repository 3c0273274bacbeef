"""Truth ephemeris (DE421) and Mars frames, against outside numbers and an independent almanac.

Mars24 (Allison and McEwen 2000) was fitted independently of our DE421 + IAU 2009 chain,
so close agreement of Ls, the sub-solar point and the heliocentric distance checks the
kernel reading, the light time, the pole and the prime meridian together.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest
from jplephem.spk import SPK

from estimation.mars_constants import MARS_ROTATION_RATE_RAD_S
from sim.errors import InputError
from sim.world.ephemeris import (
    AU_KM,
    C_KM_S,
    apparent_dir_from_mars_j2000,
    astrometric_from_mars_j2000_km,
    coverage_t_s,
    de421_path,
    mars_heliocentric_distance_au,
    mars_velocity_j2000_km_s,
)
from sim.world.mars_frames import (
    R_ll_mf,
    R_mf_j2000,
    azimuth_rad,
    earth_ll_truth,
    elevation_rad,
    iau_mars_angles_rad,
    ll_from_elevation_azimuth,
    mars_rotation_ll,
    planetocentric_from_planetographic,
    planetographic_from_planetocentric,
    sun_ll_truth,
)
from sim.world.marsclock import mars24_at_t_s, utc_to_t_s

T_2004 = utc_to_t_s(datetime(2004, 1, 1, tzinfo=UTC))
T_2030 = utc_to_t_s(datetime(2030, 1, 1, tzinfo=UTC))
SITES_DEG = [(-14.57, 175.48), (-1.95, 354.47), (0.0, 0.0), (45.0, 90.0), (-60.0, 270.0)]


def _angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    out: np.ndarray = np.degrees(np.arccos(np.clip(np.sum(a * b, axis=-1), -1.0, 1.0)))
    return out


def test_closest_approach_of_2003() -> None:
    # NASA/JPL: Earth and Mars closest on 2003-08-27 09:51 UT, 55,758,006 km apart.
    t0 = utc_to_t_s(datetime(2003, 8, 27, 9, 51, tzinfo=UTC))
    t = t0 + np.arange(-86_400.0, 86_401.0, 300.0)
    d_km = np.linalg.norm(astrometric_from_mars_j2000_km("earth", t), axis=-1)
    assert d_km.min() == pytest.approx(55_758_006.0, abs=500.0)
    assert abs(t[np.argmin(d_km)] - t0) <= 20 * 60


def test_light_time_against_an_independent_kernel_read() -> None:
    # Read DE421 directly: Earth at t - τ minus Mars at t must be our vector, τ = |p| / c.
    kernel = SPK.open(str(de421_path()))
    t = np.array([T_2004, 0.5 * (T_2004 + T_2030), T_2030])
    p = astrometric_from_mars_j2000_km("earth", t)
    tau_s = np.linalg.norm(p, axis=-1) / C_KM_S
    jd = (t - tau_s) / 86_400.0
    earth = kernel[0, 3].compute(2451545.0, jd) + kernel[3, 399].compute(2451545.0, jd)
    mars = kernel[0, 4].compute(2451545.0, t / 86_400.0) + kernel[4, 499].compute(
        2451545.0, t / 86_400.0
    )
    kernel.close()
    assert np.allclose(p, (earth - mars).T, atol=1e-3)  # km
    assert np.all(tau_s > 180.0) and np.all(tau_s < 1_400.0)  # 3 to 23 light-minutes


def test_aberration_is_mars_orbital_speed_over_c() -> None:
    t = np.linspace(T_2004, T_2030, 100)
    u = apparent_dir_from_mars_j2000("sun", t)
    p = astrometric_from_mars_j2000_km("sun", t)
    p /= np.linalg.norm(p, axis=-1, keepdims=True)
    shift_arcsec = _angle_deg(u, p) * 3600.0
    v = mars_velocity_j2000_km_s(t)
    v_perp = np.linalg.norm(np.cross(v, p), axis=-1)
    assert np.allclose(np.radians(shift_arcsec / 3600.0), v_perp / C_KM_S, rtol=1e-4)
    assert shift_arcsec.min() > 14.0 and shift_arcsec.max() < 19.0  # 22-26.5 km/s


def test_outside_de421_is_an_input_error() -> None:
    first, last = coverage_t_s()
    for t in (first - 86_400.0, last + 86_400.0, float("nan")):
        with pytest.raises(InputError) as err:
            sun_ll_truth(t, 0.0, 0.0)
        assert err.value.parameter == "utc"


def test_mars24_and_de421_agree_on_ls_subsolar_point_and_distance() -> None:
    rng = np.random.default_rng(5)
    t = rng.uniform(utc_to_t_s(datetime(1990, 1, 1)), utc_to_t_s(datetime(2050, 1, 1)), 200)
    u = apparent_dir_from_mars_j2000("sun", t)
    # Ls: longitude of the Sun in Mars' orbit plane from Mars' vernal equinox.
    p = astrometric_from_mars_j2000_km("sun", t)
    normal = np.cross(-p, mars_velocity_j2000_km_s(t))
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    R = R_mf_j2000(t)
    equinox = np.cross(R[..., 2, :], normal)
    equinox /= np.linalg.norm(equinox, axis=-1, keepdims=True)
    ls = np.degrees(np.arctan2(np.sum(u * np.cross(normal, equinox), -1), np.sum(u * equinox, -1)))
    u_mf = np.einsum("...ij,...j->...i", R, u)
    sub_lon_west = -np.degrees(np.arctan2(u_mf[:, 1], u_mf[:, 0]))
    dec_graphic = np.degrees(planetographic_from_planetocentric(np.arcsin(u_mf[:, 2])))
    m24 = [mars24_at_t_s(float(x)) for x in t]

    def wrap(x: np.ndarray) -> np.ndarray:
        return (x + 180.0) % 360.0 - 180.0

    assert np.abs(wrap(ls - [m.ls_deg for m in m24])).max() < 0.012  # measured 0.0085
    assert np.abs(wrap(sub_lon_west - [m.subsolar_lon_west_deg for m in m24])).max() < 0.015
    assert np.abs(dec_graphic - [m.solar_declination_deg for m in m24]).max() < 0.03
    r_au = mars_heliocentric_distance_au(t)
    assert np.abs(r_au - [m.heliocentric_distance_au for m in m24]).max() < 4e-4


def test_mars24_zenith_formula_differs_from_the_rigorous_geometry_by_tenths() -> None:
    # Mars24's planetographic declination in a spherical formula vs ephemeris + ellipsoid.
    rng = np.random.default_rng(9)
    t = rng.uniform(T_2004, T_2030, 60)
    worst = []
    for lat_deg, lon_east_deg in [*SITES_DEG, (70.0, 10.0)]:
        truth = sun_ll_truth(t, math.radians(lat_deg), math.radians(lon_east_deg))
        m24 = [mars24_at_t_s(float(x), lat_deg, (360.0 - lon_east_deg) % 360.0) for x in t]
        almanac = ll_from_elevation_azimuth(
            np.radians([m.sun_elev_deg for m in m24]), np.radians([m.sun_azimuth_deg for m in m24])
        )
        worst.append(_angle_deg(truth, almanac).max())
    assert max(worst) < 0.35  # measured 0.25 deg
    assert min(worst) > 0.1  # genuinely independent computations


def test_iau_rotation_pole_and_rate() -> None:
    t = np.array([-1e9, 0.0, 3e8, 1.5e9])
    alpha0, delta0, _ = iau_mars_angles_rad(t)
    R = R_mf_j2000(t)
    pole_j2000 = np.stack(
        [np.cos(delta0) * np.cos(alpha0), np.cos(delta0) * np.sin(alpha0), np.sin(delta0)], -1
    )
    assert np.allclose(np.einsum("...ij,...j->...i", R, pole_j2000), [0.0, 0.0, 1.0], atol=1e-12)
    assert np.allclose(R @ np.swapaxes(R, -1, -2), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0)
    # One second later the frame has turned by Ω about the pole.
    dR = R_mf_j2000(t + 1.0) @ np.swapaxes(R, -1, -2)
    angle = np.arccos((np.trace(dR, axis1=-2, axis2=-1) - 1.0) / 2.0)
    assert np.allclose(angle, MARS_ROTATION_RATE_RAD_S, rtol=1e-6)


def test_ll_frame_axes() -> None:
    for lat_deg, lon_deg in SITES_DEG:
        R = R_ll_mf(math.radians(lat_deg), math.radians(lon_deg))
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-15)
        assert np.linalg.det(R) == pytest.approx(1.0)
        # North and Down lie in the meridian plane; Down points below the horizon of the pole.
        assert R[0] @ [0.0, 0.0, 1.0] == pytest.approx(math.cos(math.radians(lat_deg)))
    # At lat 0, lon 0: North = +z, East = +y, Down = -x.
    assert np.allclose(R_ll_mf(0.0, 0.0), [[0, 0, 1], [0, 1, 0], [-1, 0, 0]], atol=1e-15)


def test_planetographic_vs_planetocentric() -> None:
    lat = np.radians(np.linspace(-90.0, 90.0, 3601))
    centric = planetocentric_from_planetographic(lat)
    assert np.allclose(planetographic_from_planetocentric(centric), lat, atol=1e-14)
    # The largest difference, at 45 deg, is atan((a^2 - b^2) / (2ab)) = 0.33825 deg.
    a, b = 3396.19, 3376.20
    assert np.degrees(np.max(lat - centric)) == pytest.approx(
        math.degrees(math.atan((a * a - b * b) / (2 * a * b))), abs=1e-5
    )
    assert np.degrees(lat[np.argmax(lat - centric)]) == pytest.approx(45.0, abs=0.2)


def test_rotation_vector_in_ll_is_the_spin_axis_seen_from_the_site() -> None:
    for lat_deg, lon_deg in [*SITES_DEG, (90.0, 0.0)]:
        lat = math.radians(lat_deg)
        expected = R_ll_mf(lat, math.radians(lon_deg)) @ [0, 0, MARS_ROTATION_RATE_RAD_S]
        assert np.allclose(mars_rotation_ll(lat), expected, atol=1e-20)
    assert np.allclose(mars_rotation_ll(math.pi / 2), [0, 0, -MARS_ROTATION_RATE_RAD_S])


def test_sun_rises_in_the_east_and_vectors_are_unit() -> None:
    lat, lon = math.radians(-14.57), math.radians(175.48)
    t0 = utc_to_t_s(datetime(2004, 1, 4, 4, 35, tzinfo=UTC))
    t = t0 + np.arange(0.0, 88_775.0, 60.0)
    sun = sun_ll_truth(t, lat, lon)
    earth = earth_ll_truth(t, lat, lon)
    assert np.allclose(np.linalg.norm(sun, axis=-1), 1.0)
    assert np.allclose(np.linalg.norm(earth, axis=-1), 1.0)
    elev = elevation_rad(sun)
    rising = np.nonzero((elev[:-1] < 0) & (elev[1:] >= 0))[0]
    setting = np.nonzero((elev[:-1] >= 0) & (elev[1:] < 0))[0]
    assert len(rising) == 1 and len(setting) == 1
    assert 0.0 < azimuth_rad(sun[rising[0]]) < math.pi  # East half
    assert math.pi < azimuth_rad(sun[setting[0]]) < 2 * math.pi  # West half
    # Elevation rate at the horizon never exceeds Ω (the Sun moves on a small circle).
    rate = np.abs(np.diff(elev)) / 60.0
    assert rate.max() < MARS_ROTATION_RATE_RAD_S * 1.01


def test_scalar_and_vector_calls_agree() -> None:
    t = T_2004 + np.array([0.0, 1e5, timedelta(days=400).total_seconds()])
    lat, lon = math.radians(10.0), math.radians(200.0)
    batch = sun_ll_truth(t, lat, lon)
    for i, ti in enumerate(t):
        assert np.allclose(sun_ll_truth(float(ti), lat, lon), batch[i], atol=1e-15)
    assert AU_KM == 149_597_870.7
