"""Visual odometry end to end on stereo pairs rendered exactly in this file (Cheng, Maimone and
Matthies 2005 sec. 2; estimation/vo/odometry.py and everything under it).

The renderer is deliberately tiny and independent of sim/: the terrain is a few textured
planes (the ground and a rising bank), each pixel of each eye is a ray of the rig's pinhole
model intersected with them, and the texture is multi-octave value noise, blurred and read
bilinearly, so that a rendered pair is the exact image of a known scene. Pixels are
supersampled, then 8-bit quantised with a little sensor noise.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from scipy import ndimage
from scipy.spatial.transform import Rotation

from estimation.vo.features import detect_features
from estimation.vo.geometry import PointedPair
from estimation.vo.odometry import VisualOdometry, VoMotion, VoResult, VoStatus
from estimation.vo.params import VoParams
from estimation.vo.sanity import SanityLimits
from estimation.vo.search import PaddedImage
from estimation.vo.stereo import stereo_points
from estimation.vo.stereo_rig import NAVCAM, StereoRig

# ----------------------------------------------------------------------------- renderer


class Texture:
    """Albedo on a plane: value noise at several scales (spacing m, amplitude), each a grid
    of Gaussian noise blurred by one cell and interpolated bilinearly."""

    def __init__(
        self,
        rng: np.random.Generator,
        octaves: tuple[tuple[float, float], ...] = ((0.01, 0.5), (0.04, 0.3), (0.16, 0.25)),
        extent_m: float = 9.0,
    ) -> None:
        self.extent_m = extent_m
        self.layers = []
        for spacing, amplitude in octaves:
            n = int(2 * extent_m / spacing) + 2
            grid = ndimage.gaussian_filter(rng.standard_normal((n, n)), 1.0).astype(np.float32)
            self.layers.append((spacing, amplitude, grid / grid.std()))

    def __call__(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        out = np.full(a.shape, 0.5)
        for spacing, amplitude, grid in self.layers:
            coords = [(a + self.extent_m) / spacing, (b + self.extent_m) / spacing]
            out += 0.12 * amplitude * ndimage.map_coordinates(grid, coords, order=1, mode="nearest")
        return out


@dataclass(frozen=True)
class Plane:
    """The terrain surface ``normal_s . x = offset_m`` bounding the solid on the side the
    unit ``normal_s`` points to (Site frame: z down)."""

    normal_s: np.ndarray
    offset_m: float
    texture: Texture

    def texture_at(self, p_s: np.ndarray) -> np.ndarray:
        e1 = np.array([1.0, 0.0, 0.0]) - self.normal_s * self.normal_s[0]
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(self.normal_s, e1)
        return self.texture(p_s @ e1, p_s @ e2)


def terrain(rng: np.random.Generator, octaves: tuple[tuple[float, float], ...] | None = None
            ) -> list[Plane]:  # fmt: skip
    """Level ground (z_s = 0) and a bank rising at 35 deg from x_s = 5 m."""
    a = math.radians(35.0)
    bank = np.array([math.sin(a), 0.0, math.cos(a)])  # into the solid: forward and down
    textures = [Texture(rng) if octaves is None else Texture(rng, octaves) for _ in range(2)]
    return [
        Plane(np.array([0.0, 0.0, 1.0]), 0.0, textures[0]),
        Plane(bank, float(bank @ [5.0, 0.0, 0.0]), textures[1]),
    ]


def render_eye(rig: StereoRig, planes: list[Plane], R_s_b: np.ndarray, p_b_s: np.ndarray,
               az: float, el: float, right_eye: bool, supersample: int) -> np.ndarray:  # fmt: skip
    """One eye's image in [0, 1]: the mean of ``supersample``² rays per pixel."""
    cam = rig.camera
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    u = (np.arange(cam.width_px)[:, None] + offsets[None, :]).ravel()
    v = (np.arange(cam.height_px)[:, None] + offsets[None, :]).ravel()
    uu, vv = np.meshgrid(u, v)
    rays_cam = np.stack([(uu - cam.c_u_px) / cam.f_px, (vv - cam.c_v_px) / cam.f_px,
                         np.ones_like(uu)], axis=-1)  # fmt: skip
    rays_s = rays_cam @ (R_s_b @ rig.R_b_cam(az, el)).T
    eye_b = rig.eye_centres_b(az, el)[1 if right_eye else 0]
    origin_s = p_b_s + R_s_b @ eye_b
    nearest = np.full(uu.shape, np.inf)
    which = np.full(uu.shape, -1)
    for i, plane in enumerate(planes):
        towards = rays_s @ plane.normal_s  # > 0: the ray enters this plane's solid
        t = (plane.offset_m - origin_s @ plane.normal_s) / np.where(towards > 0, towards, 1.0)
        hit = (towards > 0) & (t > 0) & (t < nearest)
        nearest = np.where(hit, t, nearest)
        which = np.where(hit, i, which)
    albedo = np.full(uu.shape, 0.3)  # sky (never in view here)
    for i, plane in enumerate(planes):
        m = which == i
        albedo[m] = plane.texture_at(origin_s + rays_s[m] * nearest[m][:, None])
    s = supersample
    out: np.ndarray = albedo.reshape(cam.height_px, s, cam.width_px, s).mean(axis=(1, 3))
    return out


def render_pair(rig: StereoRig, planes: list[Plane], R_s_b: np.ndarray, p_b_s: np.ndarray,
                az: float, el: float, rng: np.random.Generator, supersample: int = 2,
                noise_dn: float = 0.5) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Left and right 8-bit images of the terrain from the body pose (R_s_b, p_b_s)."""
    images = []
    for right in (False, True):
        dn = 255.0 * render_eye(rig, planes, R_s_b, p_b_s, az, el, right, supersample)
        dn += rng.normal(0.0, noise_dn, dn.shape)
        images.append(np.clip(np.rint(dn), 0, 255).astype(np.uint8))
    return images[0], images[1]


# ----------------------------------------------------------------------------- scenario

P_B0_S = np.array([0.0, 0.0, -0.30])  # body origin 0.30 m above the ground
R_S_B0 = Rotation.from_euler("ZYX", [5.0, 3.0, -2.0], degrees=True).as_matrix()
# Truth: 30 cm forward, 3 cm right, 1 cm down, turning 3 deg right with a little pitch/roll.
R_B0_B1 = Rotation.from_euler("ZYX", [3.0, 0.5, -0.3], degrees=True).as_matrix()
P_B1_B0 = np.array([0.30, 0.03, 0.01])
# Wheel odometry believed 50 cm straight ahead: 20 cm of slip and 3 deg of heading error.
R_WHEELS = np.eye(3)
P_WHEELS = np.array([0.50, 0.0, 0.0])
AZ0, EL0 = math.radians(10.0), math.radians(-35.0)


@dataclass(frozen=True)
class Pairs:
    rig: StereoRig
    first: tuple[np.ndarray, np.ndarray]
    second: tuple[np.ndarray, np.ndarray]
    az1: float


def _render_scenario(width_px: int, supersample: int, az1: float, seed: int = 1) -> Pairs:
    rng = np.random.default_rng(seed)
    rig = NAVCAM.at_resolution(width_px)
    planes = terrain(rng)
    R_s_b1 = R_S_B0 @ R_B0_B1
    p_b1_s = P_B0_S + R_S_B0 @ P_B1_B0
    first = render_pair(rig, planes, R_S_B0, P_B0_S, AZ0, EL0, rng, supersample)
    second = render_pair(rig, planes, R_s_b1, p_b1_s, az1, EL0, rng, supersample)
    return Pairs(rig, first, second, az1)


@pytest.fixture(scope="module")
def pairs_256() -> Pairs:
    # The mast turns 4 deg between the pairs: the frames must carry it.
    return _render_scenario(256, 2, AZ0 + math.radians(4.0))


def _run(pairs: Pairs, params: VoParams | None = None) -> tuple[VisualOdometry, VoResult]:
    vo = VisualOdometry(pairs.rig, params)
    first = vo.step(*pairs.first, R_b0_b1_predicted=np.eye(3), p_b1_b0_predicted=np.zeros(3),
                    R_s_b0=R_S_B0, mast_az_rad=AZ0, mast_el_rad=EL0)  # fmt: skip
    assert first.status is VoStatus.INITIALISED and first.motion is None
    assert first.n_features > 150
    second = vo.step(*pairs.second, R_b0_b1_predicted=R_WHEELS, p_b1_b0_predicted=P_WHEELS,
                     R_s_b0=R_S_B0, mast_az_rad=pairs.az1, mast_el_rad=EL0)  # fmt: skip
    return vo, second


def _errors(motion: VoMotion | None) -> tuple[np.ndarray, np.ndarray]:
    """Position error (m) and rotation error (rad, rotation vector) against the truth."""
    assert motion is not None
    p_err = motion.p_b1_b0 - P_B1_B0
    r_err = Rotation.from_matrix(motion.R_b0_b1 @ R_B0_B1.T).as_rotvec()
    return p_err, r_err


# ----------------------------------------------------------------------------- tests


def test_a_step_recovers_the_true_motion_despite_slip(pairs_256: Pairs) -> None:
    _, result = _run(pairs_256)
    assert result.status is VoStatus.CONVERGED, result.reason
    motion = result.motion
    assert motion is not None
    p_err, r_err = _errors(motion)
    assert np.linalg.norm(p_err) < 0.01  # 1 cm, against 20 cm of wheel-odometry error
    assert math.degrees(np.linalg.norm(r_err)) < 0.1
    assert result.n_inliers >= 60
    # The reported covariance is consistent with the actual error (chi-square, 6 dof, 99.9 %).
    e = np.concatenate([-r_err, -p_err])  # truth minus estimate, (θ, δp) as documented
    assert e @ np.linalg.solve(motion.covariance, e) < 22.5
    # The update VO makes to wheel odometry: the 20 cm of slip, in Site coordinates.
    assert result.update is not None
    dp_s = result.update.dp_s
    np.testing.assert_allclose(dp_s, R_S_B0 @ (P_B1_B0 - P_WHEELS), atol=0.01)


def test_full_resolution_step() -> None:
    pairs = _render_scenario(1024, 1, AZ0, seed=2)
    _, result = _run(pairs)
    assert result.status is VoStatus.CONVERGED, result.reason
    p_err, r_err = _errors(result.motion)
    assert np.linalg.norm(p_err) < 0.005 and math.degrees(np.linalg.norm(r_err)) < 0.05


def test_stereo_matches_are_subpixel_on_the_rendered_pair(pairs_256: Pairs) -> None:
    rig = pairs_256.rig
    pair = PointedPair.from_rig(rig, AZ0, EL0)
    params = VoParams().for_width(256)
    left, right = (PaddedImage(im, 80) for im in pairs_256.first)
    uv, _ = detect_features(
        left.image, n_features=params.n_features, cell_px=params.grid_cell_px,
        min_separation_px=params.min_separation_px, border_px=params.window_px,
        block_px=params.harris_block_px, aperture_px=params.harris_aperture_px,
        harris_k=params.harris_k,
    )  # fmt: skip
    found = stereo_points(
        pair, left, right, uv, params.min_disparity_px, params.max_disparity_px,
        window_px=params.window_px, row_slack_px=params.row_slack_px,
        min_score=params.min_score, cov_scale=params.peak_cov_scale,
        min_sigma_px=params.min_sigma_px, max_gap_m=params.max_gap_m,
        max_range_m=params.max_range_m,
    )  # fmt: skip
    assert found.ok.sum() > 150
    # Truth: intersect each left pixel's ray with the terrain, project into the right eye.
    planes = terrain(np.random.default_rng(1))  # geometry only; textures are irrelevant
    rays_b, _ = pair.rays_b(uv[found.ok])
    origin_s = P_B0_S + R_S_B0 @ pair.c_left_b
    rays_s = rays_b @ R_S_B0.T
    t = np.full(len(rays_s), np.inf)
    for plane in planes:
        towards = rays_s @ plane.normal_s
        hit_t = (plane.offset_m - origin_s @ plane.normal_s) / np.where(towards > 0, towards, 1)
        t = np.where((towards > 0) & (hit_t > 0), np.minimum(t, hit_t), t)
    p_b = (origin_s + rays_s * t[:, None] - P_B0_S) @ R_S_B0  # back to the body frame
    _, uv_right_true = pair.project(p_b)
    error = found.uv_right_px[found.ok] - uv_right_true
    assert np.median(np.abs(error[:, 0])) < 0.1  # disparity, px
    assert np.percentile(np.abs(error[:, 0]), 95) < 0.3
    assert np.median(np.abs(error[:, 1])) < 0.1  # the row stays on the epipolar line
    # Triangulated points lie on the terrain within their own 3-sigma.
    miss = found.p_b[found.ok] - p_b
    sigma = np.sqrt(np.einsum("ni,nij,nj->n", miss, np.linalg.inv(found.cov_b[found.ok]), miss))
    assert np.percentile(sigma, 90) < 3.0


def test_a_featureless_scene_fails_instead_of_guessing() -> None:
    """Flat albedo (the smooth Meridiani fines of sec. 4.1) with sensor noise only."""
    rng = np.random.default_rng(3)
    rig = NAVCAM.at_resolution(256)
    planes = terrain(rng, octaves=((0.5, 0.0),))
    first = render_pair(rig, planes, R_S_B0, P_B0_S, AZ0, EL0, rng, noise_dn=2.0)
    second = render_pair(rig, planes, R_S_B0 @ R_B0_B1, P_B0_S + R_S_B0 @ P_B1_B0, AZ0, EL0,
                         rng, noise_dn=2.0)  # fmt: skip
    vo = VisualOdometry(rig)
    vo.step(*first, R_b0_b1_predicted=np.eye(3), p_b1_b0_predicted=np.zeros(3),
            R_s_b0=R_S_B0, mast_az_rad=AZ0, mast_el_rad=EL0)  # fmt: skip
    result = vo.step(*second, R_b0_b1_predicted=R_WHEELS, p_b1_b0_predicted=P_WHEELS,
                     R_s_b0=R_S_B0, mast_az_rad=AZ0, mast_el_rad=EL0)  # fmt: skip
    assert result.status is VoStatus.TOO_FEW_FEATURES
    assert not result.converged and result.motion is None
    assert "need" in result.reason


def test_an_update_beyond_the_sanity_limits_is_no_update(pairs_256: Pairs) -> None:
    """The same good estimate, refused when the update limit is below the 20 cm of slip."""
    strict = dataclasses.replace(VoParams().for_width(256), sanity=SanityLimits(max_update_m=0.1))
    _, result = _run(pairs_256, strict)
    assert result.status is VoStatus.INSANE_UPDATE
    assert result.motion is None and "update magnitude" in result.reason
    assert result.update is not None and np.linalg.norm(result.update.dp_s) > 0.1


@pytest.mark.parametrize(
    ("changes", "status", "words"),
    [
        ({"ransac_threshold_px": 1e-6}, VoStatus.TOO_FEW_INLIERS, "RANSAC inliers"),
        ({"ml_max_iterations": 1, "ml_tol_rad": 1e-15, "ml_tol_m": 1e-15},
         VoStatus.NO_CONVERGENCE, "did not converge"),
        ({"min_features": 190, "min_inliers": 12}, VoStatus.TOO_FEW_FEATURES, "need 190"),
    ],
)  # fmt: skip
def test_each_failure_is_no_update(
    pairs_256: Pairs, changes: dict[str, Any], status: VoStatus, words: str
) -> None:
    params = dataclasses.replace(VoParams().for_width(256), **changes)
    _, result = _run(pairs_256, params)
    assert result.status is status and words in result.reason
    assert result.motion is None and not result.converged


def test_images_and_poses_are_validated(pairs_256: Pairs) -> None:
    vo = VisualOdometry(pairs_256.rig)
    left, right = pairs_256.first
    kw: dict[str, Any] = {"R_b0_b1_predicted": np.eye(3), "p_b1_b0_predicted": np.zeros(3),
          "R_s_b0": R_S_B0, "mast_az_rad": AZ0, "mast_el_rad": EL0}  # fmt: skip
    with pytest.raises(ValueError, match="left"):
        vo.step(left[:100], right, **kw)
    with pytest.raises(ValueError, match="right"):
        vo.step(left, np.full(right.shape, np.nan), **kw)
    with pytest.raises(ValueError, match="R_b0_b1_predicted"):
        vo.step(left, right, **{**kw, "R_b0_b1_predicted": 2 * np.eye(3)})
    with pytest.raises(ValueError, match="p_b1_b0_predicted"):
        vo.step(left, right, **{**kw, "p_b1_b0_predicted": [0.0, np.inf, 0.0]})
    with pytest.raises(ValueError, match="mast_el_rad"):
        vo.step(left, right, **{**kw, "mast_el_rad": math.nan})
    # Nothing was stored by the refused calls: the next good pair initialises.
    assert vo.step(left, right, **kw).status is VoStatus.INITIALISED
    vo.reset()
    assert vo.step(left, right, **kw).status is VoStatus.INITIALISED


def test_a_checkpoint_between_pairs_resumes_bit_for_bit(pairs_256: Pairs) -> None:
    """``state()`` after the first pair, through JSON, onto a fresh ``VisualOdometry``: the
    second step (tracking, RANSAC's samples, the ML refinement) gives the same result."""
    from tests.estimation.sapp.test_nate_state import assert_same, through_json

    original = VisualOdometry(pairs_256.rig)
    original.step(*pairs_256.first, R_b0_b1_predicted=np.eye(3), p_b1_b0_predicted=np.zeros(3),
                  R_s_b0=R_S_B0, mast_az_rad=AZ0, mast_el_rad=EL0)  # fmt: skip
    original.rng.random(3)  # the generator has moved: its position must travel too
    restored = VisualOdometry(pairs_256.rig)
    restored.load_state(through_json(original.state()))
    assert_same(restored.state(), original.state())
    kw: dict[str, Any] = {
        "R_b0_b1_predicted": R_WHEELS,
        "p_b1_b0_predicted": P_WHEELS,
        "R_s_b0": R_S_B0,
        "mast_az_rad": pairs_256.az1,
        "mast_el_rad": EL0,
    }
    second_r = restored.step(*pairs_256.second, **kw)
    second_o = original.step(*pairs_256.second, **kw)
    assert second_o.status is VoStatus.CONVERGED
    assert_same(second_r, second_o)
