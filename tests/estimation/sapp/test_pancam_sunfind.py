"""Pancam camera model, mast pointing, sun image rendering and the onboard sun finder."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.typing import NDArray

from estimation.camera_model import PANCAM, PinholeCamera, R_b_pancam, mast_az_el_for
from estimation.sapp.sunfind import (
    SUN_ANGULAR_RADIUS_MAX_RAD,
    SUN_ANGULAR_RADIUS_MIN_RAD,
    find_sun,
)
from sim.errors import InputError
from sim.sensors.pancam import (
    PancamDetector,
    SolarFilter,
    render_sun_image,
    render_sun_stamp,
    sun_angular_radius_rad,
    sun_disk_rate_e_s,
)

MARS_PERIHELION_AU = 1.3814  # NASA Mars fact sheet
MARS_APHELION_AU = 1.6660  # NASA Mars fact sheet


def angle_between_deg(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    return math.degrees(math.atan2(np.linalg.norm(np.cross(a, b)), float(a @ b)))


def sun_at_pixel(u: float, v: float, az: float, el: float) -> NDArray[np.float64]:
    """Body-frame sun direction that images at pixel (u, v) with the mast at (az, el)."""
    out: NDArray[np.float64] = R_b_pancam(az, el) @ PANCAM.unproject(u, v)
    return out


# --- camera model -----------------------------------------------------------------------


def test_pancam_scale_matches_the_published_ifov() -> None:
    # Bell et al. 2003: 0.27-0.28 mrad/pixel, 16 deg across 1024 pixels.
    assert 0.27e-3 <= PANCAM.ifov_centre_rad <= 0.28e-3
    u, v = PANCAM.project(np.array([math.tan(math.radians(8.0)), 0.0, 1.0]))
    assert float(u) == pytest.approx(1023.5)  # the field edge is the detector edge
    assert float(v) == pytest.approx(511.5)


def test_project_unproject_round_trip() -> None:
    rng = np.random.default_rng(0)
    u = rng.uniform(-0.5, 1023.5, 1000)
    v = rng.uniform(-0.5, 1023.5, 1000)
    rays = PANCAM.unproject(u, v)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=1), 1.0, atol=1e-15)
    u2, v2 = PANCAM.project(rays * rng.uniform(0.1, 100.0, (1000, 1)))  # any range
    np.testing.assert_allclose(u2, u, atol=1e-9)
    np.testing.assert_allclose(v2, v, atol=1e-9)
    # x right, y down: a ray to the right and below the boresight lands right and below.
    ur, vr = PANCAM.project(np.array([0.01, 0.02, 1.0]))
    assert float(ur) > PANCAM.c_u_px and float(vr) > PANCAM.c_v_px
    assert np.all(PANCAM.in_image(u2, v2))
    assert not PANCAM.in_image(-0.6, 10.0) and not PANCAM.in_image(10.0, 1023.6)
    # Behind the camera there is no image.
    ub, vb = PANCAM.project(np.array([0.0, 0.0, -1.0]))
    assert math.isnan(float(ub)) and math.isnan(float(vb))


def test_cahv_vectors_reproduce_the_projection() -> None:
    rng = np.random.default_rng(1)
    R_w_cam = R_b_pancam(0.7, 0.3)
    c_w = np.array([0.45, 0.0, -1.2])
    C, A, H, V = PANCAM.cahv(R_w_cam, c_w)
    p_cam = np.column_stack([rng.uniform(-1, 1, 200), rng.uniform(-1, 1, 200), np.full(200, 8.0)])
    p_w = c_w + p_cam @ R_w_cam.T
    d = p_w - C
    u_cahv = d @ H / (d @ A)  # Yakimovsky-Cunningham CAHV projection
    v_cahv = d @ V / (d @ A)
    u, v = PANCAM.project(p_cam)
    np.testing.assert_allclose(u_cahv, u, atol=1e-9)
    np.testing.assert_allclose(v_cahv, v, atol=1e-9)


def test_mast_pointing_convention() -> None:
    R0 = R_b_pancam(0.0, 0.0)
    np.testing.assert_allclose(R0[:, 2], [1.0, 0.0, 0.0], atol=1e-15)  # boresight +x
    np.testing.assert_allclose(R0[:, 0], [0.0, 1.0, 0.0], atol=1e-15)  # image right: +y
    np.testing.assert_allclose(R0[:, 1], [0.0, 0.0, 1.0], atol=1e-15)  # image down: Down
    up = R_b_pancam(0.0, math.pi / 2)
    np.testing.assert_allclose(up[:, 2], [0.0, 0.0, -1.0], atol=1e-15)  # el 90: up = -z
    right = R_b_pancam(math.pi / 2, 0.0)  # clockwise about Down: looking right
    np.testing.assert_allclose(right[:, 2], [0.0, 1.0, 0.0], atol=1e-15)
    rng = np.random.default_rng(2)
    for az, el in zip(rng.uniform(-math.pi, math.pi, 20), rng.uniform(-1.5, 1.5, 20), strict=True):
        R = R_b_pancam(az, el)
        np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-14)
        assert np.linalg.det(R) == pytest.approx(1.0)
        az2, el2 = mast_az_el_for(R[:, 2])
        assert az2 == pytest.approx(az) and el2 == pytest.approx(el)


# --- renderer ----------------------------------------------------------------------------


def test_sun_angular_size_from_mars() -> None:
    # docs/REFERENCES.md: about 0.35 deg across at 1.52 AU.
    assert math.degrees(2 * sun_angular_radius_rad(1.52)) == pytest.approx(0.35, abs=0.005)
    # The flight software's size bounds agree with the simulator's geometry.
    rmax = sun_angular_radius_rad(MARS_PERIHELION_AU)
    rmin = sun_angular_radius_rad(MARS_APHELION_AU)
    assert rmax == pytest.approx(SUN_ANGULAR_RADIUS_MAX_RAD, rel=1e-3)
    assert rmin == pytest.approx(SUN_ANGULAR_RADIUS_MIN_RAD, rel=1e-3)


@pytest.mark.parametrize("uv", [(511.5, 511.5), (300.25, 700.6), (40.3, 985.8)])
def test_noise_free_disk_is_centred_and_carries_the_whole_flux(uv: tuple[float, float]) -> None:
    det = PancamDetector()
    rho = sun_angular_radius_rad(1.52)
    rate = sun_disk_rate_e_s(1.52, 0.6, SolarFilter())
    stamp = render_sun_stamp(PANCAM.unproject(*uv), PANCAM, det, rho, 0.45, rate)
    assert stamp is not None
    img = stamp.rate_e_s
    rows, cols = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    u_c = (img * (cols + stamp.col0)).sum() / img.sum()
    v_c = (img * (rows + stamp.row0)).sum() / img.sum()
    assert u_c == pytest.approx(uv[0], abs=0.005)
    assert v_c == pytest.approx(uv[1], abs=0.005)
    # The flux of the disk is the same anywhere: the per-ray solid angle (cos^3) offsets
    # the stretched projection near the corner (11 deg off-axis, a 6 % effect).
    assert img.sum() == pytest.approx(rate, rel=2e-3)
    # The disk is ~22 pixels across: pixels above half the peak cover ~pi r^2.
    r_px = rho * PANCAM.f_px
    assert np.count_nonzero(img > 0.5 * img.max()) == pytest.approx(math.pi * r_px**2, rel=0.1)


def test_autoexposure_puts_the_peak_at_70_percent_of_full_well() -> None:
    det = PancamDetector()
    rng = np.random.default_rng(3)
    for _ in range(5):
        u, v = rng.uniform(100, 900, 2)
        shot = render_sun_image(sun_at_pixel(u, v, 0.4, 0.6), 0.4, 0.6, rng)
        assert shot.image.dtype == np.uint16
        assert shot.image.shape == (1024, 1024)
        peak_fraction = (
            (shot.image.max() - det.dark_offset_dn) * det.gain_e_per_dn / det.full_well_e
        )
        assert 0.6 <= peak_fraction <= 0.8
        assert shot.image.max() < 4095  # far from saturation
        assert 0.01 < shot.exposure_s < 1.0  # a plausible Pancam sun exposure
        assert shot.truth_uv_px is not None
        np.testing.assert_allclose(shot.truth_uv_px, [u, v], atol=1e-9)


def test_out_of_field_image_is_just_noise() -> None:
    det = PancamDetector()
    rng = np.random.default_rng(4)
    shot = render_sun_image(np.array([-1.0, 0.0, 0.0]), 0.0, 0.3, rng)  # sun behind
    assert shot.truth_uv_px is None
    assert shot.peak_e == 0.0
    img = shot.image.astype(np.float64)
    assert img.mean() == pytest.approx(det.dark_offset_dn, abs=0.02)
    read_dn = det.read_noise_e / det.gain_e_per_dn
    assert img.std() == pytest.approx(math.sqrt(read_dn**2 + 1 / 12), rel=0.03)
    assert img.max() < det.dark_offset_dn + 7.0 * read_dn


def test_renderer_rejects_bad_input() -> None:
    rng = np.random.default_rng(0)
    with pytest.raises(InputError, match="sun_b"):
        render_sun_image(np.zeros(3), 0.0, 0.0, rng)
    with pytest.raises(InputError, match="sun_distance_au"):
        render_sun_image(np.array([1.0, 0.0, 0.0]), 0.0, 0.0, rng, sun_distance_au=-1.0)
    with pytest.raises(InputError, match="peak_fraction"):
        render_sun_image(np.array([1.0, 0.0, 0.0]), 0.0, 0.0, rng, peak_fraction=1.5)


# --- sun finder --------------------------------------------------------------------------


def test_sun_finder_accuracy_over_200_images() -> None:
    rng = np.random.default_rng(2026)
    errors_deg = []
    pixel_errors = []
    for _ in range(200):
        az = rng.uniform(-math.pi, math.pi)
        el = rng.uniform(0.0, math.radians(70.0))
        u, v = rng.uniform(24.0, 999.0, 2)  # the whole disk inside the frame
        sun_b = sun_at_pixel(u, v, az, el)
        dist_au = rng.uniform(MARS_PERIHELION_AU, MARS_APHELION_AU)
        shot = render_sun_image(sun_b, az, el, rng, sun_distance_au=dist_au)
        fix = find_sun(shot.image, PANCAM, R_b_pancam(az, el))
        assert fix is not None
        assert np.linalg.norm(fix.sun_b) == pytest.approx(1.0)
        errors_deg.append(angle_between_deg(fix.sun_b, sun_b))
        assert shot.truth_uv_px is not None
        pixel_errors.append(np.linalg.norm(fix.centroid_uv_px - shot.truth_uv_px))
    rms_deg = math.sqrt(np.mean(np.square(errors_deg)))
    # The acceptance figure is 0.02 deg (1 sigma); we measure ~4e-5 deg (0.0025 px).
    assert rms_deg <= 0.02
    assert rms_deg <= 2e-4
    assert max(pixel_errors) < 0.05


def test_no_sun_in_the_field_is_not_found() -> None:
    rng = np.random.default_rng(5)
    R = R_b_pancam(0.0, 0.5)
    behind = render_sun_image(np.array([-1.0, 0.0, 0.0]), 0.0, 0.5, rng)
    assert find_sun(behind.image, PANCAM, R) is None
    off_axis = R @ np.array([math.sin(math.radians(30.0)), 0.0, math.cos(math.radians(30.0))])
    assert find_sun(render_sun_image(off_axis, 0.0, 0.5, rng).image, PANCAM, R) is None
    # Just beyond the edge: the disk (radius ~11 px) misses the detector.
    beyond = sun_at_pixel(-20.0, 400.0, 0.0, 0.5)
    assert find_sun(render_sun_image(beyond, 0.0, 0.5, rng).image, PANCAM, R) is None


@pytest.mark.parametrize("uv", [(2.0, 500.0), (1021.0, 300.0), (600.0, 8.0), (12.0, 1012.0)])
def test_sun_cut_by_the_edge_is_rejected(uv: tuple[float, float]) -> None:
    rng = np.random.default_rng(6)
    shot = render_sun_image(sun_at_pixel(*uv, 1.0, 0.2), 1.0, 0.2, rng)
    assert shot.image.max() > 1000  # the partial disk is plainly there...
    assert find_sun(shot.image, PANCAM, R_b_pancam(1.0, 0.2)) is None  # ...and refused


def test_cosmic_ray_hits_are_not_suns() -> None:
    rng = np.random.default_rng(7)
    R = R_b_pancam(0.0, 0.5)
    dark = render_sun_image(np.array([-1.0, 0.0, 0.0]), 0.0, 0.5, rng).image.copy()
    dark[100, 200] = 4095
    dark[700, 701:704] = 4095  # a grazing track, 3 pixels
    assert find_sun(dark, PANCAM, R) is None
    sun_b = sun_at_pixel(480.3, 530.7, 0.0, 0.5)
    shot = render_sun_image(sun_b, 0.0, 0.5, rng).image.copy()
    shot[100, 200] = 4095
    fix = find_sun(shot, PANCAM, R)
    assert fix is not None
    assert angle_between_deg(fix.sun_b, sun_b) < 1e-3


def test_sun_finder_rejects_malformed_input() -> None:
    img = np.zeros((1024, 1024), dtype=np.uint16)
    with pytest.raises(ValueError, match="image"):
        find_sun(img[:512], PANCAM, np.eye(3))
    with pytest.raises(ValueError, match="R_b_cam"):
        find_sun(img, PANCAM, 2.0 * np.eye(3))
    small = PinholeCamera.from_fov(64, 64, math.radians(16.0))
    assert find_sun(np.zeros((64, 64), dtype=np.uint16), small, np.eye(3)) is None
