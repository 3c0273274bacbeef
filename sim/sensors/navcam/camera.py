"""Navcam stereo pairs of the simulated terrain: ray-cast, sun-lit, shadowed, noisy.

One call, :func:`render_navcam_pair`, images the terrain through the rectified stereo rig
of ``estimation.vo.stereo_rig`` (MER Navcam: 1024 x 1024, 45 deg, 20 cm baseline, mast
head ~1.5 m above the ground; Maki et al. 2003, JGR 108(E12) 8071) from a rover pose, a
mast pointing and a Sun direction, and returns both eyes' images with what produced them.

Geometry -- exactly the rig's pinhole model: pixel ``(col, row)`` of either eye is the ray
through camera point ``((col - c_u)/f, (row - c_v)/f, 1)`` (``estimation.camera_model``:
the first pixel's centre is ``(0, 0)``), so a point at camera ``(x, y, z)`` is drawn at
``u = f x/z + c_u``, ``v = f y/z + c_v``. The eyes share the orientation
``R_s_cam = R_s_b(q_s_b) @ rig.R_b_cam(az, el)`` and sit at ``p_s + R_s_b @
rig.eye_centres_b(az, el)``: the right eye ``+baseline`` along camera x, so a point at
depth ``z`` has disparity ``u_left - u_right = f B / z``. Rendering is at the rig's own
resolution (``NAVCAM.at_resolution(256)`` renders MER's 256 x 256 VO images directly; the
texture is band-limited to the pixel footprint, see below), one ray per pixel centre.

What is drawn (``sim.sensors.navcam.trace`` casts the rays):

- The terrain surface at full geometric detail: the heightmap (rocks included) sampled on
  its own 5 cm lattice around the view (analytic terrains on a 5 cm grid), the surface
  between samples bilinear -- for a ``HeightmapTerrain`` exactly ``terrain.height_m``.
- Reflectance from the terrain's albedo evaluated at each pixel's ground point. For the
  sites' procedural texture (``sim.world.albedo``) detail finer than ``TEXTURE_BLUR`` pixel
  footprints fades to its mean (the footprint: distance / f, stretched by ``1/sqrt(cos)``
  of the incidence of the line of sight -- the geometric mean of the footprint ellipse's
  axes -- both seen from the eyes' midpoint, so the two eyes band-limit a ground point
  alike): the stand-in for the pixels' area and the optics' blur. Any other terrain's
  ``albedo(x, y)`` is point-sampled.
- Lambertian shading (radiance factor ``I/F``, the reflectance of the scene as a camera
  calibrated in ``I/F`` reports it)::

      I/F = albedo * (max(n.sun, 0) * V + skylight_fraction * (1 + n_up) / 2)

  ``V`` is 0 where the ground is in a cast shadow (a ray from the point towards the Sun
  meets terrain or rocks; with ``rover_shadow`` also the rover's body, deck, mast, camera
  bar, HGA and wheels as boxes and cylinders, the shape table of ``sim.rover.geometry``). The
  second term is Mars's diffuse skylight, which keeps shadows grey, not black.
  ``n_up`` is the normal's vertical component (the sky a tilted facet sees). The normal
  ``n`` is the smooth one interpolated from the samples' slopes (``sim.sensors.navcam.trace``):
  the 5 cm facets do not show on rocks at close range.
- Sky: rays that meet no ground within ``max_range_m`` (or beyond the sampled region) have
  a uniform ``sky_iof``.
- Not drawn: the rover itself (a ray passes through the deck; at elevations steeper than
  about -50 deg the real Navcam would see the deck), atmospheric haze, and the terrain
  beyond ``max_range_m``.

Shadows are cast by terrain within the sampled region, which reaches ``SHADOW_RISE_M /
tan(sun elevation)`` (at most ``SHADOW_REACH_MAX_M``) beyond the view towards the Sun:
taller or farther occluders (a distant hill at sunset) are not seen.

Detector (``NavcamDetector``): one exposure for both eyes, set by auto-exposure from the
left eye (its ``autoexposure_quantile`` of I/F lands at ``autoexposure_fill`` of the full
well) unless given. Images are float32 DN on the 12-bit scale. With ``noise=True``:
Poisson shot noise on the signal electrons, Gaussian read noise, the full well, the bias
offset and rounding to whole DN (values are integers in [0, 4095]); the variance of a pixel
is then ``(S + read_noise^2) / gain^2 + 1/12`` DN^2 for ``S`` signal electrons. With
``noise=False`` the expected DN (offset + signal / gain), not rounded. A downsampled
image (256 x 256) gets the same per-pixel noise as a full-resolution one (conservative:
MER's 4 x 4 averaging would lower it).

The Sun below the horizon (``sun_s`` pointing down) is an error, not a black frame: the
Navcam is not commanded at night, and a caller who asks has a bug.

Speed: the caster (``sim.sensors.navcam.trace``) and the texture
(``sim.sensors.navcam.texture``) are numba kernels, parallel over pixels; the first call in a
fresh checkout compiles them
(~10 s, then cached on disk in ``__pycache__``). On the 2-core development machine a
1024 x 1024 pair of Gusev with shadows and noise takes ~0.9 s (1.5 s of CPU: longer when
the other core is busy), a 256 x 256 pair ~0.06 s; the rover's shadow adds ~5 %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.vo.stereo_rig import NAVCAM, StereoRig
from sim.errors import InputError
from sim.sensors.navcam.rover_shadow import (
    ROVER_BOUND_B,
    ROVER_BOXES_B,
    ROVER_CYLINDERS_B,
    RoverShadow,
)
from sim.sensors.navcam.texture import band_limited_albedo
from sim.sensors.navcam.trace import HeightGrid, render_eye
from sim.world.albedo import AlbedoTexture
from sim.world.heightmap import HeightmapTerrain
from sim.world.terrain import Terrain

FloatArray = NDArray[np.float64]
Float32Array = NDArray[np.float32]

DEFAULT_EL_RAD = math.radians(-35.0)  # MER VO looked at the ground ahead, ~30-45 deg down
DEFAULT_MAX_RANGE_M = 30.0  # farther ground is sky; VO features lie within ~10 m
MAX_RANGE_LIMIT_M = 100.0  # beyond this the sampled grid gets too big (memory, time)
ANALYTIC_GRID_SPACING_M = 0.05  # grid for terrains without a lattice (the heightmap's own)
COARSE_FLOOR_STEP_M = 0.5  # spacing of the first look at the terrain's lowest point
FLOOR_MARGIN_M = 1.0  # the terrain may dip this far below the coarse samples' minimum
SHADOW_RISE_M = 3.0  # occluders up to this much above a visible point cast their shadow
SHADOW_REACH_MAX_M = 20.0  # ... but the grid reaches at most this far towards the Sun
MAX_GRID_SAMPLES = 8_000_000  # 3 float64 arrays of this size: ~200 MB; far above normal use
UNIT_TOLERANCE = 1e-6  # |norm - 1| allowed for sun_s and q_s_b
# The texture is band-limited to this many pixel footprints (octaves of lattice cells under
# 2 pixels gone, over 4 kept): the stand-in for the pixel's area and the optics' blur. A
# point-sampled texture with detail at one pixel aliases, and the two eyes sample it at
# different phases; with 2 a right row matches the left one shifted by the disparity to
# ~10 % of the texture's contrast, the rest being the grains' sharp rims (sim.world.albedo).
TEXTURE_BLUR = 2.0


@dataclass(frozen=True)
class NavcamDetector:
    """The Navcam CCD and exposure (MER engineering cameras, Maki et al. 2003).

    Full well ~170,000 e- and a 12-bit ADC (Maki et al. 2003); the gain (~full well over
    the 12-bit range), read noise (a few tens of e- for the MER CCDs at Mars temperatures)
    and bias offset are approximate. Auto-exposure: the left eye's
    ``autoexposure_quantile`` of I/F is put at ``autoexposure_fill`` of the full well
    (MER's auto-exposure also aimed a high histogram point at a fraction of full scale).
    """

    full_well_e: float = 170_000.0
    gain_e_per_dn: float = 50.0
    read_noise_e: float = 30.0
    offset_dn: float = 100.0
    adc_bits: int = 12
    autoexposure_quantile: float = 0.995
    autoexposure_fill: float = 0.75

    def __post_init__(self) -> None:
        for name in ("full_well_e", "gain_e_per_dn"):
            if not (math.isfinite(getattr(self, name)) and getattr(self, name) > 0.0):
                raise InputError(name, "must be positive and finite")
        if not (self.read_noise_e >= 0.0 and self.offset_dn >= 0.0):
            raise InputError("read_noise_e/offset_dn", "must be non-negative")
        if not 1 <= self.adc_bits <= 16:
            raise InputError("adc_bits", "must be in 1..16")
        if not (0.0 < self.autoexposure_quantile <= 1.0 and 0.0 < self.autoexposure_fill <= 1.0):
            raise InputError("autoexposure_quantile/autoexposure_fill", "must be in (0, 1]")

    @property
    def max_dn(self) -> int:
        """The largest code of the ADC (4095 for 12 bits)."""
        return (1 << self.adc_bits) - 1

    def dn_variance(self, signal_e: ArrayLike) -> FloatArray:
        """Model variance (DN^2) of a noisy pixel with ``signal_e`` expected electrons:
        shot + read noise through the gain, plus uniform rounding (1/12 DN^2)."""
        s = np.asarray(signal_e, dtype=np.float64)
        out: FloatArray = (s + self.read_noise_e**2) / self.gain_e_per_dn**2 + 1.0 / 12.0
        return out


@dataclass(frozen=True)
class MarsLight:
    """Illumination apart from the Sun's direction (approximate values).

    ``skylight_fraction``: diffuse sky irradiance on level ground over the direct solar
    irradiance on a surface facing the Sun (Mars's dusty sky, optical depth ~0.5: shadows
    at a third or so of the lit brightness). ``sky_iof``: the sky's radiance factor near
    the horizon (brighter than the ~0.2 albedo ground, as in Navcam frames).
    """

    skylight_fraction: float = 0.3
    sky_iof: float = 0.3

    def __post_init__(self) -> None:
        if not (0.0 <= self.skylight_fraction <= 10.0 and 0.0 <= self.sky_iof <= 10.0):
            raise InputError("skylight_fraction/sky_iof", "must be in [0, 10]")


NAVCAM_DETECTOR = NavcamDetector()
MARS_LIGHT = MarsLight()


@dataclass(frozen=True)
class NavcamPair:
    """A rendered stereo pair and what produced it.

    ``left``, ``right`` (H, W) float32 DN, 12-bit scale (module docstring); rows are image
    ``v``, columns ``u``. ``depth_left_m``, ``depth_right_m`` (H, W) float32: each pixel's
    ground point's camera ``z`` (along the boresight, m), NaN where the pixel sees sky.
    ``p_s``, ``q_s_b``: the rover's pose (Site frame); ``az_rad``, ``el_rad``: the mast
    pointing used; ``sun_s``: the Sun's unit vector (Site, N E Down); ``e_per_iof``: the
    exposure (signal electrons for I/F = 1); ``noisy``: whether noise was added.
    """

    left: Float32Array
    right: Float32Array
    depth_left_m: Float32Array
    depth_right_m: Float32Array
    rig: StereoRig
    p_s: FloatArray
    q_s_b: FloatArray
    az_rad: float
    el_rad: float
    sun_s: FloatArray
    e_per_iof: float
    noisy: bool
    detector: NavcamDetector = field(default=NAVCAM_DETECTOR)

    def R_s_cam(self) -> FloatArray:
        """Rotation taking (either eye's) camera coordinates to the Site frame."""
        out: FloatArray = Rotation.from_quat(self.q_s_b).as_matrix() @ self.rig.R_b_cam(
            self.az_rad, self.el_rad
        )
        return out

    def eye_centres_s(self) -> tuple[FloatArray, FloatArray]:
        """Optical centres of the left and right eye in the Site frame (m)."""
        R_s_b = Rotation.from_quat(self.q_s_b).as_matrix()
        left_b, right_b = self.rig.eye_centres_b(self.az_rad, self.el_rad)
        return self.p_s + R_s_b @ left_b, self.p_s + R_s_b @ right_b


_UP_FROM_SITE = np.diag([1.0, 1.0, -1.0])  # (N, E, Down) <-> the caster's (N, E, Up)


@dataclass(frozen=True)
class _Eye:
    """One eye's ray-cast products (H, W): range, depth, hit (Site x, y), shading terms."""

    range_m: FloatArray
    depth_m: FloatArray
    x_s: FloatArray
    y_s: FloatArray
    direct: FloatArray
    sky_view: FloatArray
    footprint_m: FloatArray


def render_navcam_pair(
    terrain: Terrain,
    p_s: ArrayLike,
    q_s_b: ArrayLike,
    sun_s: ArrayLike,
    rig: StereoRig = NAVCAM,
    az_rad: float = 0.0,
    el_rad: float = DEFAULT_EL_RAD,
    *,
    rng: np.random.Generator | None = None,
    shadows: bool = True,
    rover_shadow: bool = False,
    noise: bool = True,
    max_range_m: float = DEFAULT_MAX_RANGE_M,
    e_per_iof: float | None = None,
    detector: NavcamDetector = NAVCAM_DETECTOR,
    light: MarsLight = MARS_LIGHT,
) -> NavcamPair:
    """Render the Navcam stereo pair of ``terrain`` seen from a rover pose.

    ``p_s`` (3,) the body origin and ``q_s_b`` (4,) ``[x, y, z, w]`` body->Site, in the
    Site frame (x North, y East, z Down; m); ``sun_s`` (3,) the unit vector to the Sun in
    the same axes (above the horizon); ``rig`` the stereo rig (its resolution is the
    image's); ``az_rad``, ``el_rad`` the mast pointing (``rig.R_b_cam``; default: straight
    ahead, 35 deg down). ``rng`` draws the noise (required when ``noise``). ``shadows``:
    cast shadows of the terrain and rocks; ``rover_shadow``: the rover's own shadow too.
    ``max_range_m``: ground farther than this (m, along the ray) is sky. ``e_per_iof``:
    a fixed exposure (electrons for I/F = 1) instead of auto-exposure.
    Raises ``InputError`` naming the bad parameter. See the module docstring.
    """
    p, q, sun = _checked_pose(p_s, q_s_b, sun_s)
    _check_options(rig, az_rad, el_rad, rng, noise, max_range_m, e_per_iof)
    R_s_b = Rotation.from_quat(q).as_matrix()
    R_s_cam = R_s_b @ rig.R_b_cam(az_rad, el_rad)
    eyes_s = [p + R_s_b @ c_b for c_b in rig.eye_centres_b(az_rad, el_rad)]
    _check_eyes_above_ground(terrain, eyes_s)
    grid = _sample_grid(terrain, eyes_s, R_s_cam, rig, sun, max_range_m)
    view = _View(grid, rig, R_s_cam, 0.5 * (eyes_s[0] + eyes_s[1]), sun, max_range_m)
    rover = RoverShadow(p, R_s_b) if rover_shadow else None
    left, right = (_cast_eye(view, eye, shadows, rover) for eye in eyes_s)
    iof_left, iof_right = (_radiance_factor(terrain, rig, light, eye) for eye in (left, right))
    if e_per_iof is None:
        e_per_iof = _autoexposure(iof_left, detector)
    return NavcamPair(
        left=_expose(iof_left, e_per_iof, detector, rng if noise else None),
        right=_expose(iof_right, e_per_iof, detector, rng if noise else None),
        depth_left_m=left.depth_m.astype(np.float32),
        depth_right_m=right.depth_m.astype(np.float32),
        rig=rig,
        p_s=p,
        q_s_b=q,
        az_rad=float(az_rad),
        el_rad=float(el_rad),
        sun_s=sun,
        e_per_iof=float(e_per_iof),
        noisy=noise,
        detector=detector,
    )


# ---- inputs ---------------------------------------------------------------------------


def _finite_vector(value: ArrayLike, name: str, n: int) -> FloatArray:
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InputError(name, f"must be a {n}-vector of numbers") from exc
    if v.shape != (n,) or not np.all(np.isfinite(v)):
        raise InputError(name, f"must be a finite {n}-vector, got shape {v.shape}")
    return v


def _checked_pose(
    p_s: ArrayLike, q_s_b: ArrayLike, sun_s: ArrayLike
) -> tuple[FloatArray, FloatArray, FloatArray]:
    p = _finite_vector(p_s, "p_s", 3)
    q = _finite_vector(q_s_b, "q_s_b", 4)
    if abs(float(np.linalg.norm(q)) - 1.0) > UNIT_TOLERANCE:
        raise InputError(
            "q_s_b", f"must be a unit quaternion [x, y, z, w], |q| = {np.linalg.norm(q):.6g}"
        )
    sun = _finite_vector(sun_s, "sun_s", 3)
    if abs(float(np.linalg.norm(sun)) - 1.0) > UNIT_TOLERANCE:
        raise InputError("sun_s", f"must be a unit vector, |sun_s| = {np.linalg.norm(sun):.6g}")
    if sun[2] >= 0.0:  # z is Down: the Sun at or below the horizon
        elev_deg = math.degrees(math.asin(min(1.0, -sun[2])))
        raise InputError(
            "sun_s",
            f"the Sun is below the horizon (elevation {elev_deg:.2f} deg): "
            "the Navcam does not image at night",
        )
    return p, q / np.linalg.norm(q), sun / np.linalg.norm(sun)


def _check_options(
    rig: StereoRig,
    az_rad: float,
    el_rad: float,
    rng: np.random.Generator | None,
    noise: bool,
    max_range_m: float,
    e_per_iof: float | None,
) -> None:
    if not isinstance(rig, StereoRig):
        raise InputError("rig", f"must be a StereoRig, got {type(rig).__name__}")
    if not math.isfinite(az_rad):
        raise InputError("az_rad", f"must be finite, got {az_rad}")
    if not (math.isfinite(el_rad) and abs(el_rad) <= 0.5 * math.pi):
        raise InputError("el_rad", f"must be in [-pi/2, pi/2], got {el_rad}")
    if noise and not isinstance(rng, np.random.Generator):
        raise InputError("rng", "a numpy.random.Generator is required when noise=True")
    if not (math.isfinite(max_range_m) and 0.0 < max_range_m <= MAX_RANGE_LIMIT_M):
        raise InputError(
            "max_range_m", f"must be in (0, {MAX_RANGE_LIMIT_M:g}] m, got {max_range_m}"
        )
    if e_per_iof is not None and not (math.isfinite(e_per_iof) and e_per_iof > 0.0):
        raise InputError("e_per_iof", f"must be positive, got {e_per_iof}")


def _check_eyes_above_ground(terrain: Terrain, eyes_s: list[FloatArray]) -> None:
    for eye in eyes_s:
        ground_m = float(terrain.height_m(eye[0], eye[1]))
        if -eye[2] <= ground_m:
            raise InputError("p_s", f"a Navcam eye is {ground_m + eye[2]:.3f} m under the terrain")


# ---- the height grid around the view --------------------------------------------------


def _frustum_directions_s(rig: StereoRig, R_s_cam: FloatArray, n: int = 17) -> FloatArray:
    """Unit rays (n*n, 3) through an n x n lattice spanning the image, edges included."""
    cam = rig.camera
    u = np.linspace(-0.5, cam.width_px - 0.5, n)
    v = np.linspace(-0.5, cam.height_px - 0.5, n)
    uu, vv = np.meshgrid(u, v)
    out: FloatArray = cam.unproject(uu.ravel(), vv.ravel()) @ R_s_cam.T
    return out


def _sample_grid(
    terrain: Terrain,
    eyes_s: list[FloatArray],
    R_s_cam: FloatArray,
    rig: StereoRig,
    sun_s: FloatArray,
    max_range_m: float,
) -> HeightGrid:
    """Sample the terrain on a grid covering all it may show and the shadows' sources.

    Each edge ray reaches ``max_range_m`` or, going down, the level ``FLOOR_MARGIN_M``
    below the lowest of coarse samples of the region, whichever is nearer; the grid spans
    those reaches from both eyes, extended towards the Sun for the shadows' casters.
    """
    spacing = getattr(terrain, "resolution_m", ANALYTIC_GRID_SPACING_M)
    if not (isinstance(spacing, float) and spacing > 0.0):
        spacing = ANALYTIC_GRID_SPACING_M
    dirs = _frustum_directions_s(rig, R_s_cam)
    eyes = np.array(eyes_s)
    far = (eyes[:, None, :] + max_range_m * dirs[None, :, :]).reshape(-1, 3)
    floor_m = _coarse_floor_m(terrain, np.vstack([eyes, far]))
    descent = dirs[:, 2]  # the Site's z is Down: positive for a ray going down
    going_down = descent > 0.0
    points = [eyes]
    for eye in eyes:
        to_floor = np.full(len(dirs), np.inf)
        to_floor[going_down] = (-eye[2] - floor_m) / descent[going_down]
        reach = np.minimum(max_range_m, to_floor)
        points.append(eye + reach[:, None] * dirs)
    pts = np.vstack(points)
    lo = pts[:, :2].min(axis=0)
    hi = pts[:, :2].max(axis=0)
    sun_xy = sun_s[:2]
    if np.hypot(*sun_xy) > 1e-9:
        sun_el = math.asin(min(1.0, -sun_s[2]))
        reach_sun = min(SHADOW_REACH_MAX_M, SHADOW_RISE_M / max(math.tan(sun_el), 1e-9))
        shift = reach_sun * sun_xy / np.hypot(*sun_xy)
        lo = np.minimum(lo, lo + shift)
        hi = np.maximum(hi, hi + shift)
    i0, j0 = (np.floor(lo / spacing) - 2).astype(np.int64)
    i1, j1 = (np.ceil(hi / spacing) + 2).astype(np.int64)
    ni, nj = int(i1 - i0 + 1), int(j1 - j0 + 1)
    if ni * nj > MAX_GRID_SAMPLES:
        raise InputError("max_range_m", f"the view needs {ni} x {nj} terrain samples; reduce it")
    if isinstance(terrain, HeightmapTerrain) and spacing == terrain.resolution_m:
        heights = _heightmap_samples(terrain, int(i0), int(j0), ni, nj)
    else:
        # x = (i0 + a) s as sim.world.noise.grid_axes forms it
        x = ((i0 + np.arange(ni, dtype=np.int64)) * spacing).astype(np.float64)
        y = ((j0 + np.arange(nj, dtype=np.int64)) * spacing).astype(np.float64)
        heights = np.asarray(terrain.height_m(x[:, None], y[None, :]), dtype=np.float64)
    return HeightGrid.from_heights(heights, float(i0 * spacing), float(j0 * spacing), spacing)


def _heightmap_samples(terrain: HeightmapTerrain, i0: int, j0: int, ni: int, nj: int) -> FloatArray:
    """The heightmap's own samples at global lattice indices ``[i0, i0+ni) x [j0, j0+nj)``,
    copied from its tiles: the grid's bilinear surface is then the terrain's, bit for bit,
    and a copy costs far less than interpolating every node."""
    cells = terrain.tile_cells
    out = np.empty((ni, nj))
    for ti in range(i0 // cells, (i0 + ni - 1) // cells + 1):
        a0, a1 = max(i0, ti * cells), min(i0 + ni, (ti + 1) * cells + 1)
        for tj in range(j0 // cells, (j0 + nj - 1) // cells + 1):
            b0, b1 = max(j0, tj * cells), min(j0 + nj, (tj + 1) * cells + 1)
            tile = terrain.tile(ti, tj)
            out[a0 - i0 : a1 - i0, b0 - j0 : b1 - j0] = tile[
                a0 - ti * cells : a1 - ti * cells, b0 - tj * cells : b1 - tj * cells
            ]
    return out


def _coarse_floor_m(terrain: Terrain, points_s: FloatArray) -> float:
    """A level (m, up) safely below the terrain over the box around ``points_s``."""
    lo = points_s[:, :2].min(axis=0)
    hi = points_s[:, :2].max(axis=0)
    x = np.arange(lo[0], hi[0] + COARSE_FLOOR_STEP_M, COARSE_FLOOR_STEP_M)
    y = np.arange(lo[1], hi[1] + COARSE_FLOOR_STEP_M, COARSE_FLOOR_STEP_M)
    h = np.asarray(terrain.height_m(x[:, None], y[None, :]))
    return float(h.min()) - FLOOR_MARGIN_M


# ---- casting and shading --------------------------------------------------------------


@dataclass(frozen=True)
class _View:
    """What both eyes share: the grid, the rig and its orientation, the mast head (the
    eyes' midpoint, Site), the Sun and the range limit."""

    grid: HeightGrid
    rig: StereoRig
    R_s_cam: FloatArray
    head_s: FloatArray
    sun_s: FloatArray
    max_range_m: float


def _cast_eye(view: _View, eye_s: FloatArray, shadows: bool, rover: RoverShadow | None) -> _Eye:
    """Cast one eye's rays over the grid (``sim.sensors.navcam.trace.render_eye``)."""
    grid = view.grid
    corner = np.array([grid.x0_m, grid.y0_m, 0.0])

    def local(point_s: FloatArray) -> FloatArray:
        out: FloatArray = _UP_FROM_SITE @ point_s - corner
        return out

    if rover is None:
        boxes, cylinders = np.zeros((0, 6)), np.zeros((0, 8))
        rover_l, R_b_l = np.zeros(3), np.eye(3)
    else:
        boxes, cylinders = ROVER_BOXES_B, ROVER_CYLINDERS_B
        rover_l, R_b_l = local(rover.p_s), rover.R_s_b.T @ _UP_FROM_SITE
    cam = view.rig.camera
    shape = (cam.height_px, cam.width_px)
    outs = [np.empty(shape) for _ in range(7)]
    render_eye(
        cam.f_px,
        cam.c_u_px,
        cam.c_v_px,
        np.ascontiguousarray(_UP_FROM_SITE @ view.R_s_cam),
        local(eye_s),
        local(view.head_s),
        view.max_range_m,
        grid.heights,
        grid.spacing_m,
        grid.grad_x,
        grid.grad_y,
        grid.max_pyramid,
        grid.level_offset,
        grid.level_ni,
        grid.level_nj,
        _UP_FROM_SITE @ view.sun_s,
        shadows,
        np.ascontiguousarray(R_b_l),
        rover_l,
        boxes,
        cylinders,
        ROVER_BOUND_B,
        *outs,
    )
    range_m, depth_m, x_l, y_l, direct, sky_view, footprint_m = outs
    return _Eye(range_m, depth_m, x_l + grid.x0_m, y_l + grid.y0_m, direct, sky_view, footprint_m)


def _albedo_at(
    terrain: Terrain, x_s: FloatArray, y_s: FloatArray, footprint_m: FloatArray
) -> FloatArray:
    """Albedo at Site points: band-limited to ``footprint_m`` for a procedural texture
    (numba, ``sim.sensors.navcam.texture``) or by the terrain itself (``albedo_band_limited``:
    a scene's, ``sim.scenarios.scene_builder``), point-sampled ``terrain.albedo`` otherwise."""
    if callable(limited := getattr(terrain, "albedo_band_limited", None)):
        return np.asarray(limited(x_s, y_s, footprint_m), dtype=np.float64)
    if isinstance(texture := getattr(terrain, "texture", None), AlbedoTexture):
        return band_limited_albedo(texture, x_s, y_s, footprint_m)
    return np.asarray(terrain.albedo(x_s, y_s), dtype=np.float64)


def _radiance_factor(terrain: Terrain, rig: StereoRig, light: MarsLight, eye: _Eye) -> FloatArray:
    """I/F image of one eye (module docstring)."""
    hit = np.flatnonzero(np.isfinite(eye.range_m.ravel()))
    footprint_m = TEXTURE_BLUR * eye.footprint_m.ravel()[hit]
    albedo = _albedo_at(terrain, eye.x_s.ravel()[hit], eye.y_s.ravel()[hit], footprint_m)
    iof = np.full(eye.range_m.size, light.sky_iof)
    iof[hit] = albedo * (
        eye.direct.ravel()[hit] + light.skylight_fraction * eye.sky_view.ravel()[hit]
    )
    return iof.reshape(eye.range_m.shape)


# ---- the detector ---------------------------------------------------------------------


def _autoexposure(iof: FloatArray, detector: NavcamDetector) -> float:
    """Electrons per unit I/F putting the image's bright quantile at the target fill."""
    sample = iof[::2, ::2].ravel()  # a quarter of the pixels: the same quantile, faster
    bright = float(np.quantile(sample, detector.autoexposure_quantile))
    return detector.autoexposure_fill * detector.full_well_e / max(bright, 1e-6)


def _expose(
    iof: FloatArray, e_per_iof: float, detector: NavcamDetector, rng: np.random.Generator | None
) -> Float32Array:
    """DN image of an I/F image: expected DN without ``rng``; with it shot noise, read noise,
    the full well, the offset and whole-DN rounding (module docstring)."""
    signal_e = np.minimum(iof * e_per_iof, detector.full_well_e)
    if rng is None:
        clean = detector.offset_dn + signal_e / detector.gain_e_per_dn
        return np.minimum(clean, detector.max_dn).astype(np.float32)
    electrons = rng.poisson(signal_e).astype(np.float64)
    np.minimum(electrons, detector.full_well_e, out=electrons)
    electrons += rng.normal(0.0, detector.read_noise_e, electrons.shape)
    dn = np.rint(detector.offset_dn + electrons / detector.gain_e_per_dn)
    return np.clip(dn, 0.0, detector.max_dn).astype(np.float32)
