"""Navcam stereo rendering (sim.sensors.navcam.camera): geometry against the rig's pinhole
model, shading, shadows, noise statistics, bad inputs, and the simulator's call."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import map_coordinates
from scipy.spatial.transform import Rotation

from estimation.vo.stereo_rig import NAVCAM
from sim.errors import InputError
from sim.loop.rover_sim import RoverSim
from sim.sensors.navcam.camera import (
    MARS_LIGHT,
    NAVCAM_DETECTOR,
    NavcamPair,
    render_navcam_pair,
)
from sim.sensors.navcam.texture import band_limited_albedo
from sim.world.sites import make_terrain
from sim.world.terrain import BEDROCK, FlatTerrain, PlaneTerrain

FloatArray = NDArray[np.float64]

RIG_256 = NAVCAM.at_resolution(256)
LEVEL = np.array([0.0, 0.0, 0.0, 1.0])  # body axes = Site axes: facing North
P_LEVEL = np.array([0.0, 0.0, -0.30])  # body origin 0.30 m above level ground at 0


def sun_from(elev_deg: float, az_deg: float) -> FloatArray:
    """Unit Sun vector in Site axes (N, E, Down) at an elevation and azimuth (from North)."""
    e, a = math.radians(elev_deg), math.radians(az_deg)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), -math.sin(e)])


def camera_of(pair: NavcamPair) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``R_s_cam`` and both eyes' centres, from the rig (independently of the renderer)."""
    R_s_b = Rotation.from_quat(pair.q_s_b).as_matrix()
    R_s_cam = R_s_b @ pair.rig.R_b_cam(pair.az_rad, pair.el_rad)
    left_b, right_b = pair.rig.eye_centres_b(pair.az_rad, pair.el_rad)
    return R_s_cam, pair.p_s + R_s_b @ left_b, pair.p_s + R_s_b @ right_b


def pixel_of(pair: NavcamPair, point_s: FloatArray, eye_s: FloatArray) -> tuple[float, float]:
    R_s_cam, _, _ = camera_of(pair)
    u, v = pair.rig.camera.project(R_s_cam.T @ (point_s - eye_s))
    return float(u), float(v)


def dn_at(image: NDArray[np.float32], uv: tuple[float, float]) -> float:
    return float(image[round(uv[1]), round(uv[0])])


class _Analytic:
    """A test terrain: level ground with optional hemispherical rock and bright disc."""

    def __init__(
        self,
        albedo: float = 0.25,
        rock: tuple[float, float, float] | None = None,
        mark: tuple[float, float, float] | None = None,
    ) -> None:
        self.name = "test"
        self.soil = BEDROCK
        self._albedo = albedo
        self._rock = rock  # (x, y, radius)
        self._mark = mark  # (x, y, radius) of a disc of albedo 1

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        if self._rock is None:
            return np.zeros(x.shape)
        xr, yr, r = self._rock
        out: FloatArray = np.sqrt(np.maximum(r * r - (x - xr) ** 2 - (y - yr) ** 2, 0.0))
        return out

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        e = 1e-6
        return (
            (self.height_m(np.add(x_m, e), y_m) - self.height_m(np.subtract(x_m, e), y_m)) / 2e-6,
            (self.height_m(x_m, np.add(y_m, e)) - self.height_m(x_m, np.subtract(y_m, e))) / 2e-6,
        )

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        out = np.full(x.shape, self._albedo)
        if self._mark is not None:
            xm, ym, r = self._mark
            out[(x - xm) ** 2 + (y - ym) ** 2 <= r * r] = 1.0
        return out


# ---- geometry -------------------------------------------------------------------------


def test_depth_map_is_the_rays_intersection_with_level_ground() -> None:
    pair = render_navcam_pair(
        FlatTerrain(), P_LEVEL, LEVEL, sun_from(40, 120), RIG_256, az_rad=0.3, noise=False
    )
    cam = pair.rig.camera
    R_s_cam, left_s, right_s = camera_of(pair)
    np.testing.assert_allclose(pair.R_s_cam(), R_s_cam, atol=1e-15)
    np.testing.assert_allclose(pair.eye_centres_s(), [left_s, right_s], atol=1e-15)
    vv, uu = np.mgrid[0:256, 0:256]
    rays_cam = cam.unproject(uu, vv)  # unit rays, (256, 256, 3)
    for eye_s, depth in ((left_s, pair.depth_left_m), (right_s, pair.depth_right_m)):
        down = rays_cam @ R_s_cam.T[:, 2]  # Site z (Down) of each unit ray
        t_ground = -eye_s[2] / down  # eye_s[2] < 0: the eye is above z = 0
        expected = np.where(down > 0.0, t_ground * rays_cam[..., 2], np.nan)
        expected[expected > 25.0] = np.nan  # beyond ~max_range (30 m along the ray): sky
        seen = np.isfinite(expected) & np.isfinite(depth)
        assert seen.sum() > 0.9 * np.isfinite(expected).sum()
        np.testing.assert_allclose(depth[seen], expected[seen], rtol=2e-6)


def test_depth_map_lies_on_the_heightmap_surface() -> None:
    terrain = make_terrain("gusev", 7)
    p = np.array([1.0, 2.0, -0.30 - float(terrain.height_m(1.0, 2.0))])
    q = Rotation.from_euler("ZYX", [0.4, 0.05, -0.03]).as_quat()
    pair = render_navcam_pair(terrain, p, q, sun_from(50, 200), RIG_256, noise=False)
    R_s_cam, left_s, _ = camera_of(pair)
    vv, uu = np.mgrid[0:256:7, 0:256:7]
    rays = pair.rig.camera.unproject(uu, vv)
    depth = pair.depth_left_m[vv, uu].astype(np.float64)
    ok = np.isfinite(depth)
    assert ok.mean() > 0.9
    points = left_s + (rays[ok] / rays[ok][:, 2:3] * depth[ok][:, None]) @ R_s_cam.T
    heights = terrain.height_m(points[:, 0], points[:, 1])
    # float32 depths at ~5 m: ~1e-6 relative; the surface itself is matched exactly
    np.testing.assert_allclose(-points[:, 2], heights, atol=2e-5)


def test_a_bright_mark_is_drawn_where_the_rig_projects_it() -> None:
    mark_s = np.array([3.0, 0.4, 0.0])
    terrain = _Analytic(albedo=0.1, mark=(mark_s[0], mark_s[1], 0.01))
    pair = render_navcam_pair(terrain, P_LEVEL, LEVEL, sun_from(60, 0), noise=False)
    _, left_s, right_s = camera_of(pair)
    seen = []
    for image, eye_s in ((pair.left, left_s), (pair.right, right_s)):
        u, v = pixel_of(pair, mark_s, eye_s)
        box = image[round(v) - 12 : round(v) + 13, round(u) - 12 : round(u) + 13]
        w = np.clip(box - np.median(box), 0.0, None).astype(np.float64)
        rows, cols = np.mgrid[0:25, 0:25]
        centroid = (
            round(u) - 12 + float((w * cols).sum() / w.sum()),
            round(v) - 12 + float((w * rows).sum() / w.sum()),
        )
        assert centroid == pytest.approx((u, v), abs=0.2)
        seen.append(centroid)
    R_s_cam, _, _ = camera_of(pair)
    z_m = float((R_s_cam.T @ (mark_s - left_s))[2])
    assert seen[0][0] - seen[1][0] == pytest.approx(pair.rig.disparity_px(z_m), abs=0.3)
    assert seen[0][1] == pytest.approx(seen[1][1], abs=0.2)  # same row: rectified


class _Ripples(_Analytic):
    """Level ground with a smooth albedo pattern, many pixels per period at 1-4 m."""

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, float), np.asarray(y_m, float))
        out: FloatArray = 0.2 + 0.05 * np.sin(2 * np.pi * x / 0.13) * np.cos(2 * np.pi * y / 0.07)
        return out


def row_mismatch(pair: NavcamPair, row: int, shift_px: float) -> tuple[float, float]:
    """RMS difference (DN) between a left row and the right row shifted by ``shift_px``
    (cubic interpolation), over the middle of the row; and the left row's spread (DN)."""
    cols = np.arange(200.0, 800.0)
    left = pair.left[row, 200:800].astype(np.float64)
    right = map_coordinates(pair.right[row].astype(np.float64), [cols - shift_px], order=3)
    return float(np.sqrt(np.mean((right - left) ** 2))), float(np.std(left))


@pytest.mark.parametrize("site", ["smooth", "flat"])
def test_a_right_row_is_the_left_row_shifted_by_f_b_over_z(site: str) -> None:
    terrain = _Ripples() if site == "smooth" else make_terrain("flat", 3)
    pair = render_navcam_pair(terrain, P_LEVEL, LEVEL, sun_from(45, 90), noise=False)
    for row in (300, 600, 900):
        depth = pair.depth_left_m[row].astype(np.float64)
        # a level plane under a camera whose x axis is level: one depth along a whole row
        assert np.ptp(depth) < 1e-5 * depth.mean()
        assert pair.depth_right_m[row] == pytest.approx(depth, rel=1e-6)
        disparity = pair.rig.disparity_px(float(depth.mean()))
        shifts = disparity + np.arange(-1.0, 1.0001, 0.05)
        errors = [row_mismatch(pair, row, s)[0] for s in shifts]
        assert abs(shifts[int(np.argmin(errors))] - disparity) <= 0.051
        error, spread = row_mismatch(pair, row, disparity)
        if site == "smooth":  # nothing finer than the pixels: the rows agree exactly
            assert error < 1e-4 * spread
        else:  # the procedural texture's finest grains alias a little (sim.sensors.navcam.camera)
            assert error < 0.2 * spread
        assert row_mismatch(pair, row, disparity + 1.0)[0] > 1.5 * error


# ---- shading and shadows --------------------------------------------------------------


def test_lambert_cosine_law_on_tilted_planes() -> None:
    sun = sun_from(40, 180)  # the Sun in the South
    e_per_iof = 2.0e5
    det, light = NAVCAM_DETECTOR, MARS_LIGHT
    centre = (RIG_256.camera.c_u_px, RIG_256.camera.c_v_px)
    measured = {}
    for slope in (0.3, -0.3):  # rising to the North: faces the Sun; rising to the South: away
        plane = PlaneTerrain(slope, 0.0, albedo_value=0.2)
        pair = render_navcam_pair(
            plane, P_LEVEL, LEVEL, sun, RIG_256, e_per_iof=e_per_iof, noise=False
        )
        iof = (dn_at(pair.left, centre) - det.offset_dn) * det.gain_e_per_dn / e_per_iof
        normal_s = np.array([-slope, 0.0, -1.0]) / math.hypot(slope, 1.0)  # up, Down axes
        cos_i = float(normal_s @ sun)
        sky = light.skylight_fraction * 0.5 * (1.0 + 1.0 / math.hypot(slope, 1.0))
        assert iof == pytest.approx(0.2 * (cos_i + sky), rel=1e-5)
        measured[slope] = (iof / 0.2 - sky, cos_i)
    (direct_to, cos_to), (direct_away, cos_away) = measured[0.3], measured[-0.3]
    assert cos_to > cos_away > 0.0
    assert direct_to / direct_away == pytest.approx(cos_to / cos_away, rel=1e-4)


def test_a_rock_casts_its_shadow_away_from_a_low_sun() -> None:
    terrain = _Analytic(albedo=0.25, rock=(3.0, -0.3, 0.2))  # 0.2 m high hemisphere
    sun = sun_from(15, 270)  # low in the West: the shadow runs East, 0.2/tan(15°) = 0.75 m
    lit = render_navcam_pair(
        terrain, P_LEVEL, LEVEL, sun, shadows=False, e_per_iof=2.0e5, noise=False
    )
    shaded = render_navcam_pair(terrain, P_LEVEL, LEVEL, sun, e_per_iof=2.0e5, noise=False)
    _, left_s, _ = camera_of(shaded)
    behind = pixel_of(shaded, np.array([3.0, 0.15, 0.0]), left_s)
    sunward = pixel_of(shaded, np.array([3.0, -0.75, 0.0]), left_s)
    beyond = pixel_of(shaded, np.array([3.0, 0.75, 0.0]), left_s)
    offset = NAVCAM_DETECTOR.offset_dn
    ratio_in_shadow = (dn_at(shaded.left, behind) - offset) / (dn_at(lit.left, behind) - offset)
    sky = MARS_LIGHT.skylight_fraction
    assert ratio_in_shadow == pytest.approx(sky / (math.sin(math.radians(15)) + sky), rel=1e-4)
    for uv in (sunward, beyond):
        assert dn_at(shaded.left, uv) == dn_at(lit.left, uv)


def test_the_rover_shadow_appears_only_when_asked() -> None:
    sun = sun_from(30, 180)  # behind the rover, which faces North: its shadow falls ahead
    args = (FlatTerrain(), P_LEVEL, LEVEL, sun, RIG_256)
    plain = render_navcam_pair(*args, e_per_iof=2.0e5, noise=False)
    ground = np.isfinite(plain.depth_left_m)
    assert np.ptp(plain.left[ground]) < 1e-3  # uniform: level ground, one albedo, no shadow
    with_rover = render_navcam_pair(*args, rover_shadow=True, e_per_iof=2.0e5, noise=False)
    darker = with_rover.left < plain.left - 1.0
    assert 0.01 < darker[ground].mean() < 0.5
    _, left_s, _ = camera_of(with_rover)
    # the mast (body y = -0.30) throws a thin shadow North; 0.3 m beside it is lit
    in_mast_shadow = pixel_of(with_rover, np.array([2.5, -0.30, 0.0]), left_s)
    beside = pixel_of(with_rover, np.array([2.5, -0.60, 0.0]), left_s)
    assert dn_at(with_rover.left, in_mast_shadow) < dn_at(plain.left, in_mast_shadow) - 100.0
    assert dn_at(with_rover.left, beside) == dn_at(plain.left, beside)


# ---- the detector ---------------------------------------------------------------------


def test_noise_has_the_model_variance_and_is_reproducible() -> None:
    terrain = make_terrain("gusev", 2)
    p = np.array([0.0, 0.0, -0.30 - float(terrain.height_m(0.0, 0.0))])
    args = (terrain, p, LEVEL, sun_from(45, 150), RIG_256)
    clean = render_navcam_pair(*args, e_per_iof=3.0e5, noise=False)
    a = render_navcam_pair(*args, e_per_iof=3.0e5, rng=np.random.default_rng(1))
    b = render_navcam_pair(*args, e_per_iof=3.0e5, rng=np.random.default_rng(2))
    again = render_navcam_pair(*args, e_per_iof=3.0e5, rng=np.random.default_rng(1))
    np.testing.assert_array_equal(a.left, again.left)
    np.testing.assert_array_equal(a.right, again.right)
    assert np.all(a.left == np.rint(a.left)) and a.left.max() <= 4095
    det = NAVCAM_DETECTOR
    signal_e = (clean.left.astype(np.float64) - det.offset_dn) * det.gain_e_per_dn
    assert signal_e.max() < det.full_well_e  # no saturation in this frame
    diff = a.left.astype(np.float64) - b.left.astype(np.float64)
    predicted = 2.0 * det.dn_variance(signal_e)
    assert float(np.mean(diff**2) / np.mean(predicted)) == pytest.approx(1.0, abs=0.03)
    bias = float(np.mean(a.left.astype(np.float64) - clean.left))
    assert abs(bias) < 0.05  # shot noise and rounding are unbiased


def test_autoexposure_fills_the_well_to_the_target() -> None:
    terrain = make_terrain("meridiani", 4)
    p = np.array([0.0, 0.0, -0.30 - float(terrain.height_m(0.0, 0.0))])
    pair = render_navcam_pair(terrain, p, LEVEL, sun_from(35, 60), RIG_256, noise=False)
    det = NAVCAM_DETECTOR
    signal_e = (pair.left.astype(np.float64) - det.offset_dn) * det.gain_e_per_dn
    bright = float(np.quantile(signal_e, det.autoexposure_quantile))
    assert bright == pytest.approx(det.autoexposure_fill * det.full_well_e, rel=0.01)


def test_the_texture_kernel_draws_the_sites_texture() -> None:
    texture = make_terrain("gusev", 11).texture  # type: ignore[attr-defined]
    rng = np.random.default_rng(0)
    x, y = rng.uniform(-200.0, 200.0, (2, 20000))
    footprint = 10.0 ** rng.uniform(-3.5, -1.0, 20000)
    expected = texture.evaluate(x, y, footprint)
    np.testing.assert_allclose(band_limited_albedo(texture, x, y, footprint), expected, atol=2e-6)


# ---- inputs and the simulator ---------------------------------------------------------


@pytest.mark.parametrize(
    ("change", "parameter"),
    [
        ({"sun_s": [0.0, 0.0, -0.9]}, "sun_s"),  # not a unit vector
        ({"sun_s": sun_from(-5.0, 90.0)}, "sun_s"),  # below the horizon
        ({"sun_s": [0.0, 0.0]}, "sun_s"),
        ({"q_s_b": [0.0, 0.0, 0.0, 2.0]}, "q_s_b"),
        ({"p_s": [0.0, math.nan, -0.3]}, "p_s"),
        ({"p_s": [0.0, 0.0, 1.5]}, "p_s"),  # the mast head under the ground
        ({"el_rad": math.radians(95.0)}, "el_rad"),
        ({"az_rad": math.inf}, "az_rad"),
        ({"rng": None}, "rng"),  # noise asked without a generator
        ({"max_range_m": 0.0}, "max_range_m"),
        ({"e_per_iof": -1.0}, "e_per_iof"),
        ({"rig": "navcam"}, "rig"),
    ],
)
def test_bad_inputs_name_the_parameter(change: dict[str, object], parameter: str) -> None:
    kwargs: dict[str, object] = {
        "terrain": FlatTerrain(),
        "p_s": P_LEVEL,
        "q_s_b": LEVEL,
        "sun_s": sun_from(40, 0),
        "rig": RIG_256,
        "rng": np.random.default_rng(0),
    }
    kwargs.update(change)
    with pytest.raises(InputError, match=rf"^{parameter}:"):
        render_navcam_pair(**kwargs)  # type: ignore[arg-type]


def test_rover_sim_renders_from_its_truth_pose_and_sun() -> None:
    sim = RoverSim("gusev", 3, datetime(2004, 3, 1, 18, 0, tzinfo=UTC))  # Sun 43° up
    pair = sim.navcam_pair(0.5, rig=RIG_256)
    np.testing.assert_array_equal(pair.p_s, sim.drive_state.p_s)
    np.testing.assert_allclose(pair.sun_s, sim.sun_ll(), atol=1e-12)
    assert pair.az_rad == pytest.approx(0.5 + sim.mast_bias_rad[0], abs=1e-12)
    assert pair.el_rad == pytest.approx(math.radians(-35.0) + sim.mast_bias_rad[1], abs=1e-12)
    assert pair.noisy and pair.left.shape == (256, 256)
    assert np.isfinite(pair.depth_left_m).mean() > 0.95  # looking at the ground
    with pytest.raises(InputError, match=r"^el_rad:"):
        sim.navcam_pair(0.0, math.radians(100.0))
