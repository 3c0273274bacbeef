"""The ground's pointing advisor for visual-odometry drives: where the Navcams should look.

Cheng, Maimone and Matthies 2005, sec. 4: on Meridiani's fine sand Opportunity's drivers had
to point the Navcams at texture (VO "requires active pointing by human drivers in
feature-poor terrain", sec. 5), keep at least 60 % image overlap between adjacent frames
(sec. 4.2), avoid the sand dunes, and, after sol 235, "take the rover shadow into account"
(sec. 4.3). The advisor does that arithmetic for a planned drive from what the ground knows
and nothing else:

- the ground's map (``server.terrain.ground_map.GroundMap``: heights, the trackable-feature
  density measured in the rover's images, NaN where no image covers a cell);
- the drive: its start (the rover's last *reported* pose), its path (straight, arc, turn
  in place, ``PlannedDrive``) cut into VO steps as the rover cuts it
  (``sequences.commands.vo_step_count``), each step's attitude from the map's slope under
  the wheels;
- the Sun at the drive's time (given by the caller: the onboard ephemeris, IVP, or the
  ground's own) and the rover's shadow from the flight copy of its shape
  (``estimation.vo.shadow_mask``);
- the Navcam rig (``estimation.vo.stereo_rig``, 256 px as MER's VO images).

For each candidate pointing (a grid of mast azimuth and elevation) it casts a lattice of
rays through the image at every step onto the map and predicts, per pair of consecutive
steps:

- ``overlap``: the fraction of the first image's ground that the second image sees again;
- ``shadow``: the fraction of the image's ground in the rover's shadow (either image);
- ``featureless``: the fraction on cells whose measured density is below
  ``featureless_per_m2`` (featureless sand);
- ``features``: the trackable features, the sum of density × ground area over the ground
  both images see (each block of the image holding at most its share of the detector's
  ``features_per_image``: the detector spreads its features over the image, so far
  ground seen at a glance gives no more than its part of the image), outside the shadow
  and the featureless sand, seen at a grazing angle of at least ``min_grazing_deg``
  (correlation windows on ground seen edge-on deform too much between viewpoints), and
  with a range changing by at most ``max_scale_change`` between the two images
  (correlation does not follow a change of scale: looking along the motion, the ground
  ahead grows in the image from one step to the next). Where the map has no measured
  density, the median of the measured cells stands in (the site's prior,
  ``prior_texture_per_m2``, if none is measured).

A drive of more than ``max_pairs`` pairs of steps is judged on that many, spread evenly
along it (the advice's time stays bounded for a long drive).

The rule (``RULE``): among the candidates whose least overlap over the steps is at least
``min_overlap`` (MER's 60 %) and whose largest shadow fraction is at most
``max_shadow_fraction``, recommend the one with the most trackable features at its worst
step (ties: the larger worst overlap). If none qualifies, no recommendation, and why.

Frames (docs/CONVENTIONS.md): the mission frame ``m`` (the first Site: x North, y East, z
Down, m; the map's heights are *up*); body ``b``; ``sun_m`` the unit vector to the Sun in
``m`` (LL axes). Mast angles as ``estimation.vo.stereo_rig``: azimuth clockwise from body
+x, elevation up from the deck. Degrees at the edges (``Candidate``), radians inside.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.geometry import FLIGHT_GEOMETRY
from estimation.vo.params import VoParams
from estimation.vo.shadow_mask import in_rover_shadow, rays_meet_rover
from estimation.vo.stereo_rig import NAVCAM, StereoRig
from sequences import commands as cmd
from server.terrain.ground_map import GroundMap

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

VO_ADVICE_RIG = NAVCAM.at_resolution(256)  # MER's VO images (sec. 4)
BODY_HEIGHT_M = FLIGHT_GEOMETRY.wheel_centre_z_m + FLIGHT_GEOMETRY.wheel_radius_m
RULE = (
    "the most trackable features at the worst step, among pointings keeping every step's "
    "image overlap >= min_overlap and the rover's shadow under max_shadow_fraction of the "
    "image; ties: the larger worst overlap"
)
KINDS = ("straight", "arc", "turn")
# the eyes sit at the top of the mast, inside the shape table's mast and camera bar: a ray
# to an eye is tested against the rover only until this far from it
HEAD_CLEARANCE_M = 0.15


@dataclass(frozen=True)
class AdviceParams:
    """The candidate grid and the rule's numbers (module docstring)."""

    az_deg: tuple[float, ...] = (-120.0, -90.0, -60.0, -30.0, 0.0, 30.0, 60.0, 90.0, 120.0)
    el_deg: tuple[float, ...] = (-35.0, -45.0, -55.0)
    rays_per_side: int = 16
    min_overlap: float = 0.6  # MER's drivers (sec. 4.2)
    max_shadow_fraction: float = 0.05
    featureless_per_m2: float = 2.0  # a 256 px pair finds ~10 per m² on textured ground
    prior_texture_per_m2: float = 10.0
    min_grazing_deg: float = 30.0
    max_scale_change: float = 0.15
    max_range_m: float = 15.0
    march_m: float = 0.25
    max_pairs: int = 8
    features_per_image: float = float(VoParams().n_features)

    def __post_init__(self) -> None:
        for name in ("az_deg", "el_deg"):
            values = getattr(self, name)
            if not values or not all(
                isinstance(v, int | float) and math.isfinite(v) for v in values
            ):
                raise ValueError(f"{name}: must be a non-empty tuple of finite degrees")
        if not all(-90.0 < v < 0.0 for v in self.el_deg):
            raise ValueError("el_deg: VO looks at the ground: each in (-90, 0) deg")
        if isinstance(self.max_pairs, bool) or not 1 <= self.max_pairs <= 64:
            raise ValueError(f"max_pairs: must be in [1, 64], got {self.max_pairs}")
        if not 4 <= self.rays_per_side <= 64:
            raise ValueError(f"rays_per_side: must be in [4, 64], got {self.rays_per_side}")
        for name in ("min_overlap", "max_shadow_fraction", "max_scale_change"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"{name}: must be in [0, 1]")
        for name in ("featureless_per_m2", "prior_texture_per_m2", "min_grazing_deg"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) >= 0.0):
                raise ValueError(f"{name}: must be finite and non-negative")
        if not (0.0 < self.march_m <= 1.0 and 1.0 < self.max_range_m <= 50.0):
            raise ValueError("march_m: must be in (0, 1] m and max_range_m in (1, 50] m")


@dataclass(frozen=True)
class PlannedDrive:
    """A VO drive as commanded: ``kind`` ``straight`` (``distance_m``), ``arc``
    (``radius_m`` signed, > 0 centre on the right; ``angle_deg`` > 0) or ``turn``
    (``angle_deg``, > 0 clockwise); the rover's VO step limits."""

    kind: str
    distance_m: float = 0.0
    radius_m: float = 0.0
    angle_deg: float = 0.0
    step_max_m: float = cmd.VO_STEP_MAX_M
    step_max_deg: float = cmd.VO_STEP_MAX_DEG

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"kind: must be one of {', '.join(KINDS)}, got {self.kind!r}")
        for name in ("distance_m", "radius_m", "angle_deg", "step_max_m", "step_max_deg"):
            if not math.isfinite(getattr(self, name)):
                raise ValueError(f"{name}: must be finite")
        if self.kind == "straight" and not 0.0 < abs(self.distance_m) <= cmd.MAX_DRIVE_M:
            raise ValueError(f"distance_m: must be non-zero and at most {cmd.MAX_DRIVE_M:g} m")
        if self.kind == "arc" and not (abs(self.radius_m) > 0.0 and self.angle_deg > 0.0):
            raise ValueError("radius_m/angle_deg: an arc needs a radius and a positive angle")
        if self.kind == "turn" and self.angle_deg == 0.0:
            raise ValueError("angle_deg: a turn needs a non-zero angle")

    def step_headings(self, yaw0_rad: float) -> tuple[FloatArray, FloatArray]:
        """Body origins' ``(north, east)`` offsets from the start (n + 1, 2), m, and
        headings (n + 1,), rad, at the drive's n + 1 pairs (the start included)."""
        if self.kind == "straight":
            n = cmd.vo_step_count(abs(self.distance_m), 0.0, self.step_max_m, self.step_max_deg)
            s = np.linspace(0.0, self.distance_m, n + 1)
            heading = np.array([math.cos(yaw0_rad), math.sin(yaw0_rad)])
            return s[:, None] * heading[None, :], np.full(n + 1, yaw0_rad)
        if self.kind == "turn":
            n = cmd.vo_step_count(0.0, self.angle_deg, self.step_max_m, self.step_max_deg)
            yaw = yaw0_rad + np.radians(np.linspace(0.0, self.angle_deg, n + 1))
            return np.zeros((n + 1, 2)), yaw
        r, angle = self.radius_m, math.radians(self.angle_deg)
        n = cmd.vo_step_count(abs(r) * angle, self.angle_deg, self.step_max_m, self.step_max_deg)
        yaw = yaw0_rad + math.copysign(1.0, r) * np.linspace(0.0, angle, n + 1)

        def right(psi: FloatArray | float) -> FloatArray:
            return np.stack([-np.sin(psi), np.cos(psi)], axis=-1)

        return r * (right(yaw0_rad)[None, :] - right(yaw)), yaw


@dataclass(frozen=True)
class Candidate:
    """One pointing's prediction: mast ``az_deg``, ``el_deg``; per pair of consecutive
    steps judged (all of them, or ``max_pairs`` spread along a long drive) the trackable
    ``features``, the ``overlap``, ``shadow`` and ``featureless`` fractions; the worst of
    each over the drive; ``ok``: it meets the rule's limits."""

    az_deg: float
    el_deg: float
    features: tuple[float, ...]
    overlap: tuple[float, ...]
    shadow: tuple[float, ...]
    featureless: tuple[float, ...]
    features_min: float
    overlap_min: float
    shadow_max: float
    featureless_max: float
    ok: bool


@dataclass(frozen=True)
class Advice:
    """The candidates, the recommended one (None when none meets the limits, ``reason``
    says why), the rule, and the drive's pair count."""

    candidates: tuple[Candidate, ...]
    recommended: Candidate | None
    reason: str
    rule: str = RULE
    pairs: int = 0
    params: AdviceParams = field(default_factory=AdviceParams)


@dataclass(frozen=True)
class _View:
    """One image's ground samples at one step: points (k, 3) in ``m``, ranges, ground
    area per sample (m²), grazing angle (rad), density (per m²), shadow flags; ``hit``
    (rays,) which rays met the ground within range (the samples are those)."""

    hit: BoolArray
    g_m: FloatArray
    range_m: FloatArray
    area_m2: FloatArray
    grazing_rad: FloatArray
    density: FloatArray
    shadow: BoolArray


def body_poses(
    gmap: GroundMap, p0_m: ArrayLike, yaw0_rad: float, drive: PlannedDrive
) -> tuple[FloatArray, FloatArray]:
    """Body origins (n + 1, 3), ``m``, and ``R_m_b`` (n + 1, 3, 3) at the drive's pairs:
    each on the map's surface (the body origin ``BODY_HEIGHT_M`` above it along the
    vertical), heading along the path, pitch and roll from the map's heights under the
    wheels (a plane through the six wheel points)."""
    p0 = np.asarray(p0_m, dtype=np.float64).reshape(3)
    offsets, yaws = drive.step_headings(yaw0_rad)
    wheels_b = FLIGHT_GEOMETRY.wheel_xy_b()
    design = np.column_stack([np.ones(6), wheels_b])
    positions, rotations = [], []
    for (dn, de), yaw in zip(offsets, yaws, strict=True):
        c, s = math.cos(yaw), math.sin(yaw)
        north = p0[0] + dn + c * wheels_b[:, 0] - s * wheels_b[:, 1]
        east = p0[1] + de + s * wheels_b[:, 0] + c * wheels_b[:, 1]
        h = gmap.height_at(north, east)
        _, slope_x, slope_y = np.linalg.lstsq(design, h, rcond=None)[0]
        pitch = math.atan(slope_x)  # nose up on a rising slope: positive pitch
        roll = -math.atan(slope_y)  # right side higher: rolls left (negative about +x)
        R = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
        ground = float(gmap.height_at(np.array([p0[0] + dn]), np.array([p0[1] + de]))[0])
        positions.append([p0[0] + dn, p0[1] + de, -(ground + BODY_HEIGHT_M)])
        rotations.append(R)
    return np.array(positions), np.array(rotations)


def _rays_cam(rig: StereoRig, n: int) -> tuple[FloatArray, FloatArray]:
    """Unit rays (n², 3) through an n x n lattice of pixel-block centres, and the image
    area (pixels²) each stands for."""
    cam = rig.camera
    u = (np.arange(n) + 0.5) * cam.width_px / n - 0.5
    v = (np.arange(n) + 0.5) * cam.height_px / n - 0.5
    uu, vv = np.meshgrid(u, v)
    block = (cam.width_px / n) * (cam.height_px / n)
    return cam.unproject(uu.ravel(), vv.ravel()), np.full(n * n, block)


def _density(gmap: GroundMap, g_m: FloatArray, prior: float) -> FloatArray:
    i, j = gmap.cell_of(g_m[:, 0], g_m[:, 1])
    ny, nx = gmap.shape
    ii = np.clip(np.rint(i).astype(np.intp), 0, ny - 1)
    jj = np.clip(np.rint(j).astype(np.intp), 0, nx - 1)
    d = np.asarray(gmap.texture, dtype=np.float64)[ii, jj]
    outside = (i < -0.5) | (i > ny - 0.5) | (j < -0.5) | (j > nx - 0.5)
    return np.where(np.isfinite(d) & ~outside, d, prior)


def _cast(
    gmap: GroundMap,
    eye_m: FloatArray,
    rays_m: FloatArray,
    pixel_sr: FloatArray,
    params: AdviceParams,
) -> tuple[BoolArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """March each ray over the map; the first crossing of the surface within range.
    Returns hit (rays,), ground points (k, 3), ranges, ground areas (m²) and grazing angles."""
    t = np.arange(params.march_m, params.max_range_m + 1e-9, params.march_m)
    pts = eye_m[None, None, :] + t[None, :, None] * rays_m[:, None, :]
    h = gmap.height_at(pts[..., 0].ravel(), pts[..., 1].ravel()).reshape(pts.shape[:2])
    below = pts[..., 2] > -h  # z is Down: below the surface
    first = np.argmax(below, axis=1)
    hit = below[np.arange(len(rays_m)), first] & (first > 0)
    k = np.flatnonzero(hit)
    f = first[k]
    # linear interpolation of the crossing between the last sample above and the first below
    above_gap = -h[k, f - 1] - pts[k, f - 1, 2]
    below_gap = pts[k, f, 2] + h[k, f]
    frac = above_gap / np.maximum(above_gap + below_gap, 1e-12)
    rng = t[f - 1] + frac * params.march_m
    g = eye_m[None, :] + rng[:, None] * rays_m[k]
    eps = 0.25 * gmap.cell_m
    hx = (gmap.height_at(g[:, 0] + eps, g[:, 1]) - gmap.height_at(g[:, 0] - eps, g[:, 1])) / (
        2 * eps
    )
    hy = (gmap.height_at(g[:, 0], g[:, 1] + eps) - gmap.height_at(g[:, 0], g[:, 1] - eps)) / (
        2 * eps
    )
    normal = np.stack([-hx, -hy, -np.ones_like(hx)], axis=1)  # up, in N E Down
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    sin_graze = np.abs(np.einsum("ij,ij->i", normal, rays_m[k]))
    area = pixel_sr[k] * rng**2 / np.maximum(sin_graze, 0.05)
    return hit, g, rng, area, np.arcsin(np.clip(sin_graze, 0.0, 1.0))


def _view(
    gmap: GroundMap,
    p_m: FloatArray,
    R_m_b: FloatArray,
    az_rad: float,
    el_rad: float,
    sun_m: FloatArray,
    rig: StereoRig,
    params: AdviceParams,
    prior: float,
) -> _View:
    rays_cam, block_px2 = _rays_cam(rig, params.rays_per_side)
    R_m_cam = R_m_b @ rig.R_b_cam(az_rad, el_rad)
    left_b, right_b = rig.eye_centres_b(az_rad, el_rad)
    eye_m = p_m + R_m_b @ (0.5 * (left_b + right_b))
    cos_off = rays_cam[:, 2]
    pixel_sr = block_px2 * cos_off**3 / rig.camera.f_px**2  # solid angle of the block
    rays_m = rays_cam @ R_m_cam.T
    hit, g, rng, area, graze = _cast(gmap, eye_m, rays_m, pixel_sr, params)
    g_b = (g - p_m) @ R_m_b
    # the rover's own deck, wheels and mast hide the ground behind them (not ground the
    # Navcam sees): the ray from the point back to the eye meets a part
    hidden = rays_meet_rover(g_b, -(rays_m[hit] @ R_m_b), rng - HEAD_CLEARANCE_M)
    hit[np.flatnonzero(hit)[hidden]] = False
    keep = ~hidden
    g, rng, area, graze, g_b = g[keep], rng[keep], area[keep], graze[keep], g_b[keep]
    shadow = in_rover_shadow(g_b, R_m_b.T @ sun_m) if len(g_b) else np.zeros(0, dtype=bool)
    return _View(hit, g, rng, area, graze, _density(gmap, g, prior), shadow)


def ground_of_pixels(
    gmap: GroundMap,
    p_m: ArrayLike,
    R_m_b: ArrayLike,
    az_rad: float,
    el_rad: float,
    uv_px: ArrayLike,
    rig: StereoRig = VO_ADVICE_RIG,
    params: AdviceParams | None = None,
) -> tuple[BoolArray, FloatArray]:
    """Where on the map the pixels ``uv_px`` (N, 2) of a left image taken from body pose
    ``p_m``, ``R_m_b`` with the mast at ``(az_rad, el_rad)`` see the ground: (N,) whether
    each meets the map within range, and those points (k, 3), ``m``. The ground places the
    features it detects in the rover's images with it (the texture of ``GroundMap``)."""
    p = params if params is not None else AdviceParams()
    uv = np.asarray(uv_px, dtype=np.float64).reshape(-1, 2)
    p_m_ = np.asarray(p_m, dtype=np.float64).reshape(3)
    R = np.asarray(R_m_b, dtype=np.float64).reshape(3, 3)
    R_m_cam = R @ rig.R_b_cam(az_rad, el_rad)
    left_b, right_b = rig.eye_centres_b(az_rad, el_rad)
    eye_m = p_m_ + R @ (0.5 * (left_b + right_b))
    rays_m = rig.camera.unproject(uv[:, 0], uv[:, 1]) @ R_m_cam.T
    hit, g, _, _, _ = _cast(gmap, eye_m, rays_m, np.ones(len(uv)), p)
    return hit, g


def footprint_area_m2(
    gmap: GroundMap,
    p_m: ArrayLike,
    R_m_b: ArrayLike,
    az_rad: float,
    el_rad: float,
    rig: StereoRig = VO_ADVICE_RIG,
    params: AdviceParams | None = None,
) -> float:
    """The ground area (m²) a left image from body pose ``p_m``, ``R_m_b`` with the mast at
    ``(az_rad, el_rad)`` covers within range, the rover's own parts excepted."""
    p = params if params is not None else AdviceParams()
    sun_overhead = np.array([0.0, 0.0, -1.0])
    view = _view(gmap, np.asarray(p_m, dtype=np.float64).reshape(3),
                 np.asarray(R_m_b, dtype=np.float64).reshape(3, 3), az_rad, el_rad,
                 sun_overhead, rig, p, p.prior_texture_per_m2)  # fmt: skip
    return float(np.sum(view.area_m2))


def _seen_from(
    g_m: FloatArray, p_m: FloatArray, R_m_b: FloatArray, az_rad: float, el_rad: float,
    sun_m: FloatArray, rig: StereoRig, params: AdviceParams,
) -> tuple[BoolArray, FloatArray, BoolArray]:  # fmt: skip
    """Whether the points are in the image from another pose (and not hidden by the rover),
    their ranges there, and whether they are in the rover's shadow there (occlusion by the
    terrain neglected)."""
    R_m_cam = R_m_b @ rig.R_b_cam(az_rad, el_rad)
    left_b, right_b = rig.eye_centres_b(az_rad, el_rad)
    eye_m = p_m + R_m_b @ (0.5 * (left_b + right_b))
    v_cam = (g_m - eye_m) @ R_m_cam
    u, v = rig.camera.project(v_cam)
    rng = np.linalg.norm(v_cam, axis=1)
    inside = np.isfinite(u) & rig.camera.in_image(np.nan_to_num(u, nan=-1e9),
                                                  np.nan_to_num(v, nan=-1e9))  # fmt: skip
    inside &= rng <= params.max_range_m
    g_b = (g_m - p_m) @ R_m_b
    eye_b = 0.5 * (left_b + right_b)
    to_eye = eye_b[None, :] - g_b
    dist = np.linalg.norm(to_eye, axis=1)
    inside &= ~rays_meet_rover(
        g_b, to_eye / np.maximum(dist, 1e-9)[:, None], dist - HEAD_CLEARANCE_M
    )
    shadow = in_rover_shadow(g_b, R_m_b.T @ sun_m) if len(g_b) else np.zeros(0, dtype=bool)
    return inside, rng, shadow


def _candidate(
    gmap: GroundMap, poses: tuple[FloatArray, FloatArray], pairs: list[int], az_deg: float,
    el_deg: float, sun_m: FloatArray, rig: StereoRig, params: AdviceParams, prior: float,
) -> Candidate:  # fmt: skip
    az, el = math.radians(az_deg), math.radians(el_deg)
    positions, rotations = poses
    views = {k: _view(gmap, positions[k], rotations[k], az, el, sun_m, rig, params, prior)
             for k in sorted({i + d for i in pairs for d in (0, 1)})}  # fmt: skip
    features, overlap, shadow, featureless = [], [], [], []
    min_graze = math.radians(params.min_grazing_deg)
    rays = params.rays_per_side**2
    for k in pairs:
        a = views[k]
        n = len(a.range_m)
        if n == 0:
            features.append(0.0)
            overlap.append(0.0)
            shadow.append(0.0)
            featureless.append(0.0)
            continue
        seen, rng_b, shadow_b = _seen_from(a.g_m, positions[k + 1], rotations[k + 1], az, el,
                                           sun_m, rig, params)  # fmt: skip
        sandy = a.density < params.featureless_per_m2
        scale_ok = np.abs(a.range_m / np.maximum(rng_b, 1e-9) - 1.0) <= params.max_scale_change
        trackable = seen & ~a.shadow & ~shadow_b & ~sandy & scale_ok & (a.grazing_rad >= min_graze)
        # a block of the image holds at most its share of the detector's features
        per_block = np.minimum(a.density * a.area_m2, params.features_per_image / rays)
        features.append(float(np.sum(per_block[trackable])))
        overlap.append(float(np.mean(seen)))
        shadow.append(max(float(np.sum(a.shadow)), float(np.sum(views[k + 1].shadow))) / rays)
        featureless.append(float(np.mean(sandy)))
    ok = min(overlap) >= params.min_overlap and max(shadow) <= params.max_shadow_fraction
    return Candidate(float(az_deg), float(el_deg), tuple(features), tuple(overlap), tuple(shadow),
                     tuple(featureless), min(features), min(overlap), max(shadow),
                     max(featureless), ok)  # fmt: skip


def _unit(v: ArrayLike, name: str) -> FloatArray:
    a = np.asarray(v, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or abs(float(np.linalg.norm(a)) - 1.0) > 1e-6:
        raise ValueError(f"{name}: must be a unit 3-vector, got {v!r}")
    return a


def advise(
    gmap: GroundMap,
    p0_m: ArrayLike,
    q_b_m: ArrayLike,
    drive: PlannedDrive,
    sun_m: ArrayLike,
    params: AdviceParams | None = None,
    rig: StereoRig = VO_ADVICE_RIG,
) -> Advice:
    """Advise the pointing of ``drive`` (module docstring). ``p0_m`` (3,) the rover's
    reported position and ``q_b_m`` (4,) its reported attitude ``[x, y, z, w]`` (body to
    mission as ``q_b_ll``: ``v_b = R(q_b_m) v_m``), at the drive's start; ``sun_m`` the Sun's
    unit vector at the drive's time. Only the heading of the reported attitude is used: each
    step's tilt comes from the map."""
    p = params if params is not None else AdviceParams()
    if not isinstance(gmap, GroundMap):
        raise ValueError(f"gmap: must be a GroundMap, got {type(gmap).__name__}")
    if not isinstance(drive, PlannedDrive):
        raise ValueError(f"drive: must be a PlannedDrive, got {type(drive).__name__}")
    p0 = np.asarray(p0_m, dtype=np.float64)
    if p0.shape != (3,) or not np.all(np.isfinite(p0)):
        raise ValueError(f"p0_m: must be a finite 3-vector, got {p0_m!r}")
    q = np.asarray(q_b_m, dtype=np.float64)
    if q.shape != (4,) or not np.all(np.isfinite(q)) or abs(float(np.linalg.norm(q)) - 1.0) > 1e-6:
        raise ValueError(f"q_b_m: must be a unit quaternion [x, y, z, w], got {q_b_m!r}")
    sun = _unit(sun_m, "sun_m")
    if sun[2] >= 0.0:
        raise ValueError("sun_m: the Sun is below the horizon: no VO drive then")
    x_m = Rotation.from_quat(q).inv().apply([1.0, 0.0, 0.0])
    yaw0 = math.atan2(float(x_m[1]), float(x_m[0]))
    poses = body_poses(gmap, p0, yaw0, drive)
    measured = np.asarray(gmap.texture, dtype=np.float64)
    measured = measured[np.isfinite(measured)]
    prior = float(np.median(measured)) if measured.size else p.prior_texture_per_m2
    n_pairs = len(poses[0]) - 1  # a long drive: its pairs sampled evenly along it
    pairs = sorted(
        {round(float(k)) for k in np.linspace(0, n_pairs - 1, min(n_pairs, p.max_pairs))}
    )
    candidates = tuple(
        _candidate(gmap, poses, pairs, az, el, sun, rig, p, prior)
        for el in p.el_deg
        for az in p.az_deg
    )
    ok = [c for c in candidates if c.ok]
    if not ok:
        reason = (
            f"no pointing keeps {100 * p.min_overlap:.0f} % overlap with the rover's shadow "
            f"under {100 * p.max_shadow_fraction:.0f} % of the image"
        )
        return Advice(candidates, None, reason, pairs=len(poses[0]), params=p)
    best = max(ok, key=lambda c: (c.features_min, c.overlap_min))
    reason = (
        f"az {best.az_deg:g} deg, el {best.el_deg:g} deg: {best.features_min:.0f} trackable "
        f"features at the worst step, overlap >= {100 * best.overlap_min:.0f} %, shadow "
        f"<= {100 * best.shadow_max:.0f} %"
    )
    return Advice(candidates, best, reason, pairs=len(poses[0]), params=p)
