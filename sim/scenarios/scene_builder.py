"""Hand-made scenes for benches and tests: rocks and albedo patches placed on a site.

A scene is a terrain (the ``sim.world.terrain.Terrain`` contract) built from a base -- a
site's ground (``gusev``, ``meridiani``: its hills or ripple plains, with or without its own
rocks and texture) or ``flat`` (a level plane) -- with:

- rocks placed by hand (``RockSpec``: centre, diameter, height, footprint aspect and
  azimuth), shaped and seated as the sites' own rocks are (``sim.world.rocks``: a
  half-ellipsoid on the ground's tangent plane, stamped into the heightmap as
  ``max(ground, rock)``), so the Navcam renders them with their shading and cast shadows;
- albedo patches (``AlbedoPatch``) on a region of the Site frame (``Circle``, ``Band``,
  ``Polygon`` of ``sim.world.soil_patches``): ``featureless`` sand, a uniform albedo with
  no texture at all (the fine sand of Meridiani at its smoothest, where VO finds nothing to
  track), or ``textured``, a procedural texture of its own style (``sim.world.albedo``).
  The topmost patch containing a point (the last given) sets its albedo; elsewhere the
  base's texture, or ``base_albedo`` (uniform) when the base is untextured.

Rendering: the Navcam renderer asks a terrain with ``albedo_band_limited`` for albedo
band-limited to each pixel's footprint (``sim.sensors.navcam.camera``), and the scene
answers patch by patch with the numba texture kernel (``sim.sensors.navcam.texture``), so a
scene's textures are drawn exactly as the sites' are.

``install_scene`` puts a scene under a ``RoverSim`` (benches build sessions by site name)
and settles the rover on it where it stood.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from sim.errors import InputError
from sim.loop.rover_sim import RoverSim
from sim.rover import drive
from sim.sensors.navcam.texture import band_limited_albedo
from sim.world.albedo import AlbedoStyle, AlbedoTexture
from sim.world.heightmap import HeightmapTerrain
from sim.world.noise import GroundField, grid_axes
from sim.world.rocks import Rocks, stamp_rocks
from sim.world.sites import make_terrain, site
from sim.world.soil_patches import Band, Circle, Polygon
from sim.world.terrain import BEDROCK

FloatArray = NDArray[np.float64]
Region = Circle | Band | Polygon

BASES = ("flat", "gusev", "meridiani")
FEATURELESS = "featureless"
TEXTURED = "textured"
MAX_ROCKS = 256
MAX_PATCHES = 64


def _finite(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(name, f"must be a finite number, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class RockSpec:
    """A rock placed by hand: centre ``(x_m, y_m)`` (Site, m), equivalent-area
    ``diameter_m``, ``height_m`` of its top above the ground (default half the diameter, as
    ``sim.world.rocks``), footprint ``aspect`` (minor over major axis, in (0, 1]) and the
    long axis's ``azimuth_deg`` clockwise from North."""

    x_m: float
    y_m: float
    diameter_m: float
    height_m: float | None = None
    aspect: float = 1.0
    azimuth_deg: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "diameter_m", "aspect", "azimuth_deg"):
            _finite(name, getattr(self, name))
        if not 0.01 <= self.diameter_m <= 5.0:
            raise InputError("diameter_m", f"must be in [0.01, 5] m, got {self.diameter_m}")
        if self.height_m is not None and not 0.0 < _finite("height_m", self.height_m) <= 3.0:
            raise InputError("height_m", f"must be in (0, 3] m, got {self.height_m}")
        if not 0.0 < self.aspect <= 1.0:
            raise InputError("aspect", f"must be in (0, 1], got {self.aspect}")


@dataclass(frozen=True)
class AlbedoPatch:
    """An albedo patch on ``region``: ``kind`` ``featureless`` (uniform ``albedo``) or
    ``textured`` (the procedural ``style``, drawn from ``seed``)."""

    region: Region
    kind: str
    albedo: float = 0.13
    style: AlbedoStyle | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        if not isinstance(self.region, Circle | Band | Polygon):
            raise InputError("region", f"must be a Circle, Band or Polygon, got {self.region!r}")
        if self.kind not in (FEATURELESS, TEXTURED):
            raise InputError("kind", f"must be {FEATURELESS} or {TEXTURED}, got {self.kind!r}")
        if not 0.0 < _finite("albedo", self.albedo) < 1.0:
            raise InputError("albedo", f"must be in (0, 1), got {self.albedo}")
        if self.kind == TEXTURED and not isinstance(self.style, AlbedoStyle):
            raise InputError("style", "a textured patch needs an AlbedoStyle")


class _FlatGround:
    """A level ground at elevation 0 (``GroundField``)."""

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        return np.zeros(np.broadcast_shapes(np.shape(x_m), np.shape(y_m)))

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        x, y = grid_axes(i0, j0, n, spacing_m)
        return np.zeros((x.shape[0], y.shape[1]))


def placed_rocks(specs: Sequence[RockSpec], ground: GroundField) -> Rocks:
    """``specs`` as ``sim.world.rocks.Rocks``, each seated on the ground's tangent plane at
    its centre (forward differences over half its long axis, as ``sample_rocks``)."""
    n = len(specs)
    x = np.array([r.x_m for r in specs], dtype=np.float64)
    y = np.array([r.y_m for r in specs], dtype=np.float64)
    d = np.array([r.diameter_m for r in specs], dtype=np.float64)
    aspect = np.array([r.aspect for r in specs], dtype=np.float64)
    a, b = 0.5 * d / np.sqrt(aspect), 0.5 * d * np.sqrt(aspect)
    height = np.array([0.5 * r.diameter_m if r.height_m is None else r.height_m for r in specs])
    azimuth = np.radians([r.azimuth_deg for r in specs]).astype(np.float64)
    if n == 0:
        zero = np.zeros(0)
        return Rocks(zero, zero, zero, zero, zero, zero, zero, zero, zero, zero)
    h = 0.5 * a
    g = ground.at(np.concatenate([x, x + h, x]), np.concatenate([y, y, y + h])).reshape(3, n)
    return Rocks(x, y, d, a, b, azimuth, height, g[0], (g[1] - g[0]) / h, (g[2] - g[0]) / h)


class SceneTerrain:
    """A scene (module docstring): the heights of ``heights`` (a ``HeightmapTerrain`` with
    the placed rocks), the albedo of the patches over the base's."""

    def __init__(
        self,
        heights: HeightmapTerrain,
        base_texture: AlbedoTexture | None,
        base_albedo: float,
        patches: Sequence[AlbedoPatch],
        rocks: Rocks,
    ) -> None:
        self.heights = heights
        self.name = heights.name
        self.soil = heights.soil
        self.resolution_m = heights.resolution_m
        self.base_texture = base_texture
        self.base_albedo = float(base_albedo)
        self.patches = tuple(patches)
        self.rocks = rocks
        self._textures = [
            AlbedoTexture(p.seed, p.style) if p.kind == TEXTURED and p.style else None
            for p in self.patches
        ]

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        return self.heights.height_m(x_m, y_m)

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        return self.heights.gradient(x_m, y_m)

    def height_and_gradient(
        self, x_m: ArrayLike, y_m: ArrayLike
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        return self.heights.height_and_gradient(x_m, y_m)

    def which_patch(self, x_m: ArrayLike, y_m: ArrayLike) -> NDArray[np.int64]:
        """Index of the topmost patch at each point, -1 where none (broadcast shape)."""
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        out = np.full(x.shape, -1, dtype=np.int64)
        for k, patch in enumerate(self.patches):
            out[np.asarray(patch.region.contains(x, y), dtype=bool)] = k
        return out

    def _compose(self, x: FloatArray, y: FloatArray, footprint_m: FloatArray | None) -> FloatArray:
        which = self.which_patch(x, y).reshape(-1)
        xf, yf = x.reshape(-1), y.reshape(-1)
        fp = None if footprint_m is None else np.broadcast_to(footprint_m, x.shape).reshape(-1)
        out = np.empty(xf.shape)
        sources: list[tuple[int, AlbedoTexture | None, float]] = [
            (-1, self.base_texture, self.base_albedo)
        ] + [(k, self._textures[k], p.albedo) for k, p in enumerate(self.patches)]
        for k, texture, albedo in sources:
            sel = np.flatnonzero(which == k)
            if sel.size == 0:
                continue
            if texture is None:
                out[sel] = albedo
            elif fp is None:
                out[sel] = texture.evaluate(xf[sel], yf[sel])
            else:
                out[sel] = band_limited_albedo(texture, xf[sel], yf[sel], fp[sel])
        return out.reshape(x.shape)

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Reflectance in [0, 1] at Site points (point-sampled textures); broadcasts."""
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        return self._compose(x, y, None)

    def albedo_band_limited(
        self, x_m: FloatArray, y_m: FloatArray, footprint_m: FloatArray
    ) -> FloatArray:
        """Reflectance with every texture band-limited to ``footprint_m`` (the renderer's
        call, 1-D arrays of one length)."""
        return self._compose(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64),
                             np.asarray(footprint_m, np.float64))  # fmt: skip


def build_scene(
    base: str,
    seed: int,
    rocks: Sequence[RockSpec] = (),
    patches: Sequence[AlbedoPatch] = (),
    *,
    site_rocks: bool = True,
    site_texture: bool = True,
    base_albedo: float = 0.13,
) -> SceneTerrain:
    """A scene on ``base`` (``BASES``; the site's ground from ``seed``), with ``rocks`` and
    ``patches`` placed (module docstring). ``site_rocks``: keep the site's own rocks;
    ``site_texture``: keep its texture (else the uniform ``base_albedo``). ``flat`` has
    neither."""
    if base not in BASES:
        raise InputError("base", f"must be one of {', '.join(BASES)}, got {base!r}")
    if len(rocks) > MAX_ROCKS or len(patches) > MAX_PATCHES:
        raise InputError("rocks/patches", f"at most {MAX_ROCKS} rocks and {MAX_PATCHES} patches")
    for r in rocks:
        if not isinstance(r, RockSpec):
            raise InputError("rocks", f"must be RockSpecs, got {r!r}")
    for p in patches:
        if not isinstance(p, AlbedoPatch):
            raise InputError("patches", f"must be AlbedoPatches, got {p!r}")
    if not 0.0 < _finite("base_albedo", base_albedo) < 1.0:
        raise InputError("base_albedo", f"must be in (0, 1), got {base_albedo}")
    texture: AlbedoTexture | None = None
    if base == "flat":
        ground: GroundField = _FlatGround()
        soil, site_stamp = BEDROCK, None
    else:
        terrain = make_terrain(base, seed)
        assert isinstance(terrain, HeightmapTerrain)
        ground, soil = terrain.ground, site(base).soil
        site_stamp = terrain._stamp if site_rocks else None
        if site_texture and isinstance(terrain.texture, AlbedoTexture):
            texture = terrain.texture
    placed = placed_rocks(rocks, ground)

    def stamp(heights: FloatArray, i0: int, j0: int, spacing_m: float) -> None:
        if site_stamp is not None:
            site_stamp(heights, i0, j0, spacing_m)
        if len(placed):
            stamp_rocks(heights, placed, i0, j0, spacing_m)

    heights = HeightmapTerrain(f"scene:{base}", soil, ground, _unused_albedo, stamp=stamp)
    return SceneTerrain(heights, texture, base_albedo, patches, placed)


def _unused_albedo(x_m: FloatArray, y_m: FloatArray) -> FloatArray:
    """The heightmap's albedo field (the scene answers albedo itself): its mean grey."""
    return np.full(np.broadcast_shapes(np.shape(x_m), np.shape(y_m)), 0.2)


def install_scene(sim: RoverSim, scene: SceneTerrain) -> None:
    """Put ``scene`` under ``sim`` and settle the rover on it where it stands, with its
    heading (benches and tests: before the first command)."""
    if not isinstance(sim, RoverSim):
        raise InputError("sim", f"must be a RoverSim, got {type(sim).__name__}")
    if not isinstance(scene, SceneTerrain):
        raise InputError("scene", f"must be a SceneTerrain, got {type(scene).__name__}")
    state = sim.drive_state
    yaw = float(np.arctan2(*_heading_ne(state.q_s_b)[::-1]))
    sim.terrain = scene
    sim.drive_state = drive.initial_state(
        scene, sim.t_s, x_m=float(state.p_s[0]), y_m=float(state.p_s[1]), yaw_rad=yaw,
        slip_model=sim.slip,
    )  # fmt: skip


def _heading_ne(q_s_b: FloatArray) -> FloatArray:
    """The body x axis's (North, East) components in the Site frame."""
    x_s = Rotation.from_quat(q_s_b).apply([1.0, 0.0, 0.0])
    return np.array([x_s[0], x_s[1]])
