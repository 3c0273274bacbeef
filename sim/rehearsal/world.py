"""A rehearsal's world: one draw of the terrain from what the ground knows of it.

The ground knows its terrain map (``sim.rehearsal.inputs.GroundMapData``: heights and their
1σ on a grid in the mission frame, and which cells some stereo pair imaged) and the site's
statistics (``sim.world.sites``). One run's terrain is a ``HeightmapTerrain`` in the MISSION
frame (x North, y East, m; heights up): the rover's true position in it is its mission-frame
position. Its ground field is the sum of

1. **the map**, interpolated by cubic convolution (Keys 1981, eq. 15 with ``a = -1/2``: the
   interpolant passes through the cells' heights and has a continuous slope, so a wheel meets
   no kink at a cell's edge). Where no stereo measured the ground the heights are the orbital
   DEM's, whose noise (tens of cm, correlated over about a post) is not relief: they are
   smoothed over ``ORBITAL_SMOOTHING_M`` first, as the ground's own planning surface does;
2. **the map's error, drawn**: a Gaussian random field of unit variance made by convolving
   white noise on the map's grid with a Gaussian kernel (the process convolution of Higdon
   2002, sec. 2), of standard deviation ``ERROR_CORRELATION_M``, scaled cell by cell by the
   map's 1σ and interpolated as the map. The correlation length sets the slopes the error adds:
   its slope's 1σ per axis is ``σ / (√2 ℓ)`` (about 4.7° for the orbital prior's 0.35 m over
   3 m; under 1° on stereo cells). It is drawn over ``WINDOW_HALF_M`` around the rover's
   reported start (a sol's drive stays inside it); beyond, the map alone;
3. **the relief the map does not resolve**: the site's own generators with the run's seed,
   their finest scales only (``UnresolvedRelief``): Gusev's decimetre roughness
   (``ColumbiaHillsGround.rough``, 2 m to 0.25 m), Meridiani's ripples and roughness
   (``RipplePlainsGround`` less its swell, less the ripples' mean);
4. **rocks** from the site's abundance (``sim.world.rocks``, Golombek and Rapp 1997, the
   run's seed), only where the map has not imaged the ground: where it has, the stereo
   resolved the rocks, and what it saw is in the map's heights;
5. under the start, the slope that settles the rover at the tilt it reported
   (``StartSlope``, set by ``sim.rehearsal.start.level_start``).

Heights are the map's (the mission frame's, up): an offset common to the whole world moves
nothing the rover senses. A tile's samples are the ground at its nodes computed separably
(``SampledGround.grid``), bit for bit the values ``at`` gives there.

The albedo is the site's texture with the run's seed (VO tracks it); the soil the site's
nominal soil with its friction angle and cohesion drawn from the priors.

A worker keeps, per process, what does not change between the runs of one campaign: the
smoothed, padded map keyed by a digest of its arrays (``map_surface``).
"""

from __future__ import annotations

import hashlib
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.ndimage import gaussian_filter, gaussian_filter1d

from sim.rehearsal.inputs import GroundMapData, Priors
from sim.world.albedo import AlbedoTexture
from sim.world.heightmap import HeightmapTerrain
from sim.world.noise import grid_axes
from sim.world.places import PLACES
from sim.world.rocks import RockField, RockPopulation, stamp_rocks
from sim.world.sites import (
    GUSEV_ALBEDO,
    GUSEV_ROCK_ABUNDANCE,
    MERIDIANI_ALBEDO,
    MERIDIANI_ROCK_ABUNDANCE,
    ColumbiaHillsGround,
    RipplePlainsGround,
    site,
)
from sim.world.terrain import Soil

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

ORBITAL_SMOOTHING_M = 3.0  # the unmeasured ground's smoothing (the ground's planning surface)
ERROR_CORRELATION_M = 3.0  # the drawn map error's Gaussian kernel σ (module docstring)
WINDOW_HALF_M = 80.0  # the map error is drawn over this half-size around the reported start
KEYS_A = -0.5  # Keys 1981: the cubic convolution kernel's parameter (third-order accurate)
_CACHE_MAPS = 4  # maps kept per process (one campaign uses one)
MIN_FRICTION_DEG, MAX_FRICTION_DEG = 15.0, 50.0  # a drawn soil stays a soil
LEVEL_INNER_M, LEVEL_OUTER_M = 1.5, 6.0  # the start's slope: whole, then fading out (StartSlope)


def _keys_weights(t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Keys 1981 eq. 15 (a = -1/2): the weights of samples -1, 0, 1, 2 at fraction ``t``."""
    a = KEYS_A
    t2, t3 = t * t, t * t * t
    w0 = a * (t3 - 2.0 * t2 + t)
    w1 = (a + 2.0) * t3 - (a + 3.0) * t2 + 1.0
    w2 = -(a + 2.0) * t3 + (2.0 * a + 3.0) * t2 - a * t
    w3 = a * (t2 - t3)
    return w0, w1, w2, w3


@dataclass(frozen=True)
class CubicGrid:
    """Samples ``values[i, j]`` at ``(north0_m + i cell_m, east0_m + j cell_m)``, interpolated
    by cubic convolution (Keys 1981); beyond the grid the edge values continue (two rows of
    padding of each edge's value, then clamped)."""

    north0_m: float
    east0_m: float
    cell_m: float
    values: FloatArray  # padded by 2 on every side

    @classmethod
    def of(cls, north0_m: float, east0_m: float, cell_m: float, values: ArrayLike) -> CubicGrid:
        padded = np.pad(np.asarray(values, dtype=np.float64), 2, mode="edge")
        return cls(float(north0_m), float(east0_m), float(cell_m), padded)

    def _axis(
        self, coord_m: FloatArray, origin_m: float, size: int
    ) -> tuple[NDArray[np.int64], tuple[FloatArray, FloatArray, FloatArray, FloatArray]]:
        """The first of the four samples about each coordinate, and their weights."""
        g = np.clip((coord_m - origin_m) / self.cell_m + 2.0, 1.0, size - 3.0)
        f = np.floor(g)
        return f.astype(np.int64) - 1, _keys_weights(g - f)

    def at(self, x_m: FloatArray, y_m: FloatArray) -> FloatArray:
        """The interpolant at points (broadcast): along x first, then along y."""
        ni, nj = self.values.shape
        i0, wi = self._axis(x_m, self.north0_m, ni)
        j0, wj = self._axis(y_m, self.east0_m, nj)
        out = np.zeros(np.shape(i0))
        for b in range(4):
            col = np.zeros(np.shape(i0))
            for a in range(4):
                col = col + wi[a] * self.values[i0 + a, j0 + b]
            out = out + wj[b] * col
        return out

    def on_axes(self, xs_m: FloatArray, ys_m: FloatArray) -> FloatArray:
        """``at`` on the grid ``xs_m`` (n,) by ``ys_m`` (m,), (n, m), separably: the same
        operations per point, so the same values bit for bit."""
        ni, nj = self.values.shape
        i0, wi = self._axis(xs_m, self.north0_m, ni)
        j0, wj = self._axis(ys_m, self.east0_m, nj)
        lo, hi = int(j0.min()), int(j0.max()) + 4
        sub = self.values[:, lo:hi]
        rows = np.zeros((xs_m.size, hi - lo))
        for a in range(4):
            rows = rows + wi[a][:, None] * sub[i0 + a]
        out = np.zeros((xs_m.size, ys_m.size))
        for b in range(4):
            out = out + wj[b][None, :] * rows[:, j0 - lo + b]
        return out


@dataclass(frozen=True)
class MapSurface:
    """What a process keeps of one ground map between runs: the map's heights (the
    unmeasured cells smoothed) as a ``CubicGrid``, its σ and its imaged cells."""

    mean: CubicGrid
    sigma_m: FloatArray
    imaged: BoolArray
    north0_m: float
    east0_m: float
    cell_m: float

    def imaged_at(self, x_m: FloatArray, y_m: FloatArray) -> BoolArray:
        """Whether the cell nearest each point was imaged (False off the map)."""
        ni, nj = self.imaged.shape
        i = np.rint((x_m - self.north0_m) / self.cell_m).astype(np.int64)
        j = np.rint((y_m - self.east0_m) / self.cell_m).astype(np.int64)
        inside = (i >= 0) & (i < ni) & (j >= 0) & (j < nj)
        out = np.zeros(np.shape(i), dtype=bool)
        out[inside] = self.imaged[i[inside], j[inside]]
        return out


_maps: OrderedDict[bytes, MapSurface] = OrderedDict()
_maps_lock = threading.Lock()


def map_digest(gmap: GroundMapData) -> bytes:
    """A digest of the map's arrays and grid (the per-process cache's key)."""
    h = hashlib.blake2b(digest_size=20)
    h.update(np.array([gmap.north0_m, gmap.east0_m, gmap.cell_m], dtype=np.float64).tobytes())
    for arr in (gmap.height_m, gmap.sigma_m, gmap.imaged):
        a = np.ascontiguousarray(arr)
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.digest()


def map_surface(gmap: GroundMapData) -> MapSurface:
    """The map's ``MapSurface``, built once per process per map (module docstring)."""
    key = map_digest(gmap)
    with _maps_lock:
        hit = _maps.get(key)
        if hit is not None:
            _maps.move_to_end(key)
            return hit
    height = np.asarray(gmap.height_m, dtype=np.float64)
    imaged = np.asarray(gmap.imaged, dtype=bool)
    smooth = gaussian_filter(height, ORBITAL_SMOOTHING_M / gmap.cell_m, mode="nearest")
    mean = CubicGrid.of(gmap.north0_m, gmap.east0_m, gmap.cell_m, np.where(imaged, height, smooth))
    surface = MapSurface(
        mean,
        np.asarray(gmap.sigma_m, dtype=np.float64).copy(),
        imaged.copy(),
        float(gmap.north0_m),
        float(gmap.east0_m),
        float(gmap.cell_m),
    )
    with _maps_lock:
        _maps[key] = surface
        while len(_maps) > _CACHE_MAPS:
            _maps.popitem(last=False)
    return surface


def map_error(
    surface: MapSurface, centre_m: tuple[float, float], rng: np.random.Generator
) -> CubicGrid | None:
    """One draw of the map's error over the window around ``centre_m`` (module docstring,
    item 2): unit-variance process convolution (Higdon 2002) times the cells' σ; None when
    the window misses the map."""
    ni, nj = surface.sigma_m.shape
    half = WINDOW_HALF_M / surface.cell_m
    ci = (centre_m[0] - surface.north0_m) / surface.cell_m
    cj = (centre_m[1] - surface.east0_m) / surface.cell_m
    i0, i1 = max(math.floor(ci - half), 0), min(math.ceil(ci + half) + 1, ni)
    j0, j1 = max(math.floor(cj - half), 0), min(math.ceil(cj + half) + 1, nj)
    if i1 - i0 < 2 or j1 - j0 < 2:
        return None
    s = ERROR_CORRELATION_M / surface.cell_m
    white = rng.standard_normal((i1 - i0, j1 - j0))
    field = gaussian_filter(white, s, mode="wrap")
    # the kernel's own variance gain: a delta's smoothed sum of squares, squared (separable)
    delta = np.zeros(int(8 * s) + 3)
    delta[delta.size // 2] = 1.0
    gain = float(np.sum(gaussian_filter1d(delta, s, mode="constant") ** 2))
    error = surface.sigma_m[i0:i1, j0:j1] * field / gain
    north0 = surface.north0_m + i0 * surface.cell_m
    east0 = surface.east0_m + j0 * surface.cell_m
    # zero beyond the window: its edge fades to nothing over two cells
    grid = CubicGrid.of(north0, east0, surface.cell_m, error)
    values = grid.values.copy()
    values[:2, :], values[-2:, :], values[:, :2], values[:, -2:] = 0.0, 0.0, 0.0, 0.0
    return replace(grid, values=values)


class UnresolvedRelief:
    """The site's relief at the scales its map does not resolve (module docstring, item 3),
    from the site's own generators and the run's seed (``GroundField``, m)."""

    def __init__(self, site_name: str, seed: int) -> None:
        self.site_name = site_name
        if site_name == "gusev":
            self._hills: ColumbiaHillsGround | None = ColumbiaHillsGround(seed)
            self._plains: RipplePlainsGround | None = None
        else:
            self._hills = None
            self._plains = RipplePlainsGround(seed)
            # the ripples' mean, ((1 + cos φ)/2)^1.5 over φ: subtracted so the map keeps its level
            phi = np.linspace(0.0, 2.0 * np.pi, 4096, endpoint=False)
            self._ripple_mean_m = float(
                RipplePlainsGround.CREST_HEIGHT_M * np.mean((0.5 * (1.0 + np.cos(phi))) ** 1.5)
            )

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        if self._hills is not None:
            out: FloatArray = self._hills.rough.at(x, y)
            return out
        assert self._plains is not None
        plains = self._plains
        fields = (
            np.zeros(x.shape),
            plains.bend.at(x, y),
            plains.strength.at(x, y),
            plains.rough.at(x, y),
        )
        out = plains._combine(x, y, *fields) + plains._datum_m - self._ripple_mean_m
        return out

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        """``at`` on a tile's grid, by the generators' separable ``grid`` (``GroundField``)."""
        if self._hills is not None:
            out: FloatArray = self._hills.rough.grid(i0, j0, n, spacing_m)
            return out
        assert self._plains is not None
        plains = self._plains
        x, y = grid_axes(i0, j0, n, spacing_m)
        fields = (
            np.zeros((n, n)),
            plains.bend.grid(i0, j0, n, spacing_m),
            plains.strength.grid(i0, j0, n, spacing_m),
            plains.rough.grid(i0, j0, n, spacing_m),
        )
        out = plains._combine(x, y, *fields) + plains._datum_m - self._ripple_mean_m
        return out


@dataclass(frozen=True)
class StartSlope:
    """A slope ``gradient`` (dh/dx, dh/dy) added about ``centre_m``: whole within
    ``LEVEL_INNER_M``, fading (smoothstep in the distance) to nothing at ``LEVEL_OUTER_M``."""

    centre_m: tuple[float, float]
    gradient: tuple[float, float]

    def at(self, x: FloatArray, y: FloatArray) -> FloatArray:
        dx, dy = x - self.centre_m[0], y - self.centre_m[1]
        r = np.clip((np.hypot(dx, dy) - LEVEL_INNER_M) / (LEVEL_OUTER_M - LEVEL_INNER_M), 0.0, 1.0)
        fade = 1.0 - r * r * (3.0 - 2.0 * r)
        out: FloatArray = (self.gradient[0] * dx + self.gradient[1] * dy) * fade
        return out


class SampledGround:
    """The run's ground field (``GroundField``): map + drawn error + unresolved relief, and
    the slope that sets the reported tilt under the start (``StartSlope``, optional)."""

    def __init__(
        self,
        surface: MapSurface,
        error: CubicGrid | None,
        relief: UnresolvedRelief,
        start_slope: StartSlope | None = None,
    ) -> None:
        self.surface, self.error, self.relief = surface, error, relief
        self.start_slope = start_slope

    def with_start_slope(self, slope: StartSlope) -> SampledGround:
        """The same ground with ``slope`` added (replacing any)."""
        return SampledGround(self.surface, self.error, self.relief, slope)

    def map_part(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """The map and its drawn error (and the start's slope), without the unresolved relief."""
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        out = self.surface.mean.at(x, y)
        if self.error is not None:
            out = out + self.error.at(x, y)
        if self.start_slope is not None:
            out = out + self.start_slope.at(x, y)
        return out

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        out: FloatArray = self.map_part(x, y) + self.relief.at(x, y)
        return out

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        x, y = grid_axes(i0, j0, n, spacing_m)
        xs, ys = x[:, 0], y[0, :]
        out = self.surface.mean.on_axes(xs, ys)
        if self.error is not None:
            out = out + self.error.on_axes(xs, ys)
        if self.start_slope is not None:
            out = out + self.start_slope.at(*np.broadcast_arrays(x, y))
        total: FloatArray = out + self.relief.grid(i0, j0, n, spacing_m)
        return total


class UnimagedRocks:
    """The site's rocks (``RockField``) kept out of the cells the map imaged: a
    ``TileStamper`` (``sim.world.heightmap``)."""

    def __init__(self, rocks: RockField, surface: MapSurface) -> None:
        self.rocks, self.surface = rocks, surface

    def stamp(self, heights: FloatArray, i0: int, j0: int, spacing_m: float) -> None:
        reach = self.rocks.population.max_semi_major_m
        n_a, n_b = heights.shape
        rocks = self.rocks.rocks_in_box(
            i0 * spacing_m - reach,
            (i0 + n_a - 1) * spacing_m + reach,
            j0 * spacing_m - reach,
            (j0 + n_b - 1) * spacing_m + reach,
        )
        if len(rocks):
            rocks = rocks.select(~self.surface.imaged_at(rocks.x_m, rocks.y_m))
        stamp_rocks(heights, rocks, i0, j0, spacing_m)


def base_site(site_name: str) -> str:
    """The site whose statistics a site or scenario place uses (``gusev``, ``meridiani``)."""
    base = PLACES[site_name].site if site_name in PLACES else site(site_name).name
    return "gusev" if base != "meridiani" else "meridiani"


def sampled_soil(site_name: str, priors: Priors, rng: np.random.Generator) -> Soil:
    """The site's nominal soil, friction angle and cohesion drawn from ``priors``."""
    nominal = site(site_name).soil
    draw = rng.standard_normal(2)
    friction = nominal.friction_angle_deg + priors.friction_sigma_deg * float(draw[0])
    cohesion = nominal.cohesion_kpa + priors.cohesion_sigma_kpa * float(draw[1])
    return replace(
        nominal,
        friction_angle_deg=min(max(friction, MIN_FRICTION_DEG), MAX_FRICTION_DEG),
        cohesion_kpa=max(cohesion, 0.0),
    )


@dataclass(frozen=True)
class SampledWorld:
    """One run's drawn world: its ground, soil, rocks and texture (``terrain`` builds it)."""

    site_name: str
    ground: SampledGround
    soil: Soil
    rocks: UnimagedRocks
    texture: AlbedoTexture

    def terrain(self) -> HeightmapTerrain:
        """The world as a ``HeightmapTerrain`` (tiles built on demand)."""
        return HeightmapTerrain(
            self.site_name, self.soil, self.ground, self.texture, stamp=self.rocks.stamp
        )

    def with_start_slope(self, slope: StartSlope) -> SampledWorld:
        """The world with ``slope`` added under the start (the rocks sit on the new ground)."""
        ground = self.ground.with_start_slope(slope)
        old = self.rocks.rocks
        rocks = RockField(old.seed, old.population, ground=ground, cell_m=old.cell_m)
        return replace(self, ground=ground, rocks=UnimagedRocks(rocks, self.rocks.surface))


def sampled_world(
    site_name: str,
    gmap: GroundMapData,
    priors: Priors,
    centre_m: tuple[float, float],
    seed: int,
    rng: np.random.Generator,
) -> SampledWorld:
    """One run's world (module docstring): ``seed`` (an int in [0, 2**63)) seeds the site's
    generators (relief, rocks, albedo), ``rng`` draws the map's error and the soil;
    ``centre_m`` the reported start (North, East, mission frame)."""
    surface = map_surface(gmap)
    error = map_error(surface, centre_m, rng)
    soil = sampled_soil(site_name, priors, rng)
    base = base_site(site_name)
    ground = SampledGround(surface, error, UnresolvedRelief(base, seed))
    if base == "gusev":
        population, albedo = RockPopulation(GUSEV_ROCK_ABUNDANCE), GUSEV_ALBEDO
    else:
        population = RockPopulation(MERIDIANI_ROCK_ABUNDANCE, d_max_m=0.5)
        albedo = MERIDIANI_ALBEDO
    rocks = UnimagedRocks(RockField(seed, population, ground=ground), surface)
    return SampledWorld(site_name, ground, soil, rocks, AlbedoTexture(seed, albedo))
