"""The named sites: where on Mars they are, and the terrain each one builds from a seed.

- ``gusev``: the Columbia Hills in Gusev crater, Spirit's field area: rolling fractal hills
  whose local slope reaches ~30° in places (Spirit drove on 20-30° slopes of Husband Hill)
  but is mostly gentler, Gusev soil, and rocks with abundance k = 0.07 (Golombek et al.
  2006 report ~5-7 % on the Gusev plains, more in the hills). The site origin is on gentler
  ground (hill relief ramps up over the first ~50 m), as Spirit landed on the plains.
- ``meridiani``: Meridiani Planum, Opportunity's plains: flat, fine basaltic sand with
  hematite spherules, small aeolian ripples (crests a few metres apart, a few cm high,
  slightly sinuous) and very few small rocks (k = 0.005).
- ``eq22``: Balaram's analytic surface, equation 22 of Balaram 2000 (``sim.world.terrain``).
- ``flat``: a level plane.

Locations: Spirit's landing site 14.57° S, 175.48° E (``gusev``, and ``eq22`` and ``flat``,
which need a place for the Sun); Opportunity's 1.95° S, 354.47° E (``meridiani``).
Latitudes are planetographic, longitudes East (docs/CONVENTIONS.md). Every terrain's ground
(before rocks) passes through elevation 0 at the Site origin.

Albedo (Lambert, approximate, from orbital albedo maps): Meridiani is among the darkest
plains on Mars (~0.12-0.15); Gusev's dusty floor is brighter (~0.2-0.25) with more contrast
between dust, soil and dark basaltic granules.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.errors import InputError
from sim.world.albedo import AlbedoStyle, AlbedoTexture, GrainLayer
from sim.world.heightmap import HeightmapTerrain
from sim.world.noise import FractalNoise, derive_key, grid_axes, lattice_uniform
from sim.world.places import PLACE_NAMES, PLACES, make_place_terrain
from sim.world.rocks import RockField, RockPopulation
from sim.world.terrain import (
    BEDROCK,
    GUSEV_SOIL,
    MERIDIANI_SAND,
    Eq22Terrain,
    FlatTerrain,
    Soil,
    Terrain,
)

FloatArray = NDArray[np.float64]

SPIRIT_LAT_DEG = -14.57  # Spirit landing site, planetographic (task brief; Golombek 2005)
SPIRIT_LON_EAST_DEG = 175.48
OPPORTUNITY_LAT_DEG = -1.95  # Opportunity landing site
OPPORTUNITY_LON_EAST_DEG = 354.47

GUSEV_ROCK_ABUNDANCE = 0.07  # k, Columbia Hills foothills (approximate)
MERIDIANI_ROCK_ABUNDANCE = 0.005  # k, Meridiani plains: almost rock free (approximate)

GUSEV_ALBEDO = AlbedoStyle(
    mean=0.22,
    contrast=0.25,
    beta=0.3,
    grains=(
        GrainLayer(cell_m=0.012, probability=0.35, relative_contrast=-0.35),  # basalt granules
        GrainLayer(cell_m=0.004, probability=0.3, relative_contrast=0.25),  # bright fines
    ),
)
MERIDIANI_ALBEDO = AlbedoStyle(
    mean=0.13,
    contrast=0.08,
    beta=0.15,
    grains=(
        GrainLayer(cell_m=0.006, probability=0.35, relative_contrast=-0.3),  # spherules
        GrainLayer(cell_m=0.0015, probability=0.5, relative_contrast=0.1),  # sand grains
    ),
)
ANALYTIC_ALBEDO = AlbedoStyle(mean=0.25, contrast=0.2, grains=GUSEV_ALBEDO.grains)


@dataclass(frozen=True)
class Site:
    """A named site: planetographic ``lat_deg`` (north positive), ``lon_east_deg``, soil.

    ``mission`` is the MER rover that landed there: its landing starts the sol count.
    """

    name: str
    lat_deg: float
    lon_east_deg: float
    soil: Soil
    description: str
    mission: str = "spirit"


_SITES = {
    s.name: s
    for s in (
        Site(
            "gusev",
            SPIRIT_LAT_DEG,
            SPIRIT_LON_EAST_DEG,
            GUSEV_SOIL,
            "Columbia Hills, Gusev crater: rolling rocky hills, slopes up to ~30°",
        ),
        Site(
            "meridiani",
            OPPORTUNITY_LAT_DEG,
            OPPORTUNITY_LON_EAST_DEG,
            MERIDIANI_SAND,
            "Meridiani Planum: flat dark sand plains with small ripples, few rocks",
            mission="opportunity",
        ),
        Site(
            "eq22",
            SPIRIT_LAT_DEG,
            SPIRIT_LON_EAST_DEG,
            BEDROCK,
            "Balaram's undulating test surface (Balaram 2000, eq. 22)",
        ),
        Site("flat", SPIRIT_LAT_DEG, SPIRIT_LON_EAST_DEG, BEDROCK, "a level plane"),
    )
}
SITE_NAMES: tuple[str, ...] = tuple(_SITES)


def site(name: str) -> Site:
    """The ``Site`` called ``name``, or the site of the scenario place ``name``
    (``sim.world.places``: ``meridiani:endurance_slope``, ...) under that name;
    InputError('site', ...) if there is none."""
    if isinstance(name, str) and name in PLACES:
        return replace(_SITES[PLACES[name].site], name=name, description=PLACES[name].description)
    if not isinstance(name, str) or name not in _SITES:
        known = ", ".join((*SITE_NAMES, *PLACE_NAMES))
        raise InputError("site", f"unknown site {name!r}; choose one of {known}")
    return _SITES[name]


def _check_seed(seed: object) -> int:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise InputError("seed", f"must be an integer, got {seed!r}")
    if not 0 <= int(seed) < 2**63:
        raise InputError("seed", f"must be in [0, 2**63), got {seed}")
    return int(seed)


class ColumbiaHillsGround:
    """Gusev ground: broad hills, steeper detail scaled by a patchy mask and by a ramp from
    the origin, and decimetre roughness. ``GroundField`` protocol (elevation up, m).

    Hill octaves run from 256 m to 4 m with amplitude ∝ cell^0.8 (a Hurst exponent of 0.8,
    approximate, typical of Mars topography at these scales). The octaves of 32 m and
    below carry most of the slope; they are multiplied by a mask (a 200 m value-noise octave)
    that leaves some areas nearly level and makes others steep, and by a ramp from 0.35 at
    the origin to 1 beyond ``RAMP_M`` (the landing plains are gentler). Both multiply a
    zero-mean field, so they change its relief, not its level. Amplitudes were tuned so the
    slope over a 1 m baseline has a median of ~5-8° and reaches 25-35° within a few hundred
    metres for most seeds (tests/sim/world/test_sites.py checks one).
    """

    RAMP_M = 50.0
    HILL_AMPLITUDE_M = 22.0  # amplitude of the 256 m octave; others scale as cell^0.8

    def __init__(self, seed: int) -> None:
        def amplitude(cell_m: float) -> float:
            return float(self.HILL_AMPLITUDE_M * (cell_m / 256.0) ** 0.8)

        broad, detail = [256.0, 128.0, 64.0], [32.0, 16.0, 8.0, 4.0]
        self.broad = FractalNoise(seed, 1, broad, [amplitude(c) for c in broad])
        self.detail = FractalNoise(seed, 4, detail, [amplitude(c) for c in detail])
        self.mask = FractalNoise(seed, 2, [200.0], [1.0])
        self.rough = FractalNoise(seed, 3, [2.0, 1.0, 0.5, 0.25], [0.03, 0.018, 0.01, 0.006])
        self._datum_m = 0.0
        self._datum_m = float(self.at(0.0, 0.0))  # elevations relative to the Site origin

    def _combine(self, x: FloatArray, y: FloatArray, *fields: FloatArray) -> FloatArray:
        broad, detail, mask, rough = fields
        m = 0.8 + 1.4 * mask  # mask within ±0.9, σ 0.28: relief x0.4-1.2 mostly, up to ~2
        r = np.minimum(np.hypot(x, y) / self.RAMP_M, 1.0)
        ramp = 0.35 + 0.65 * r * r * (3.0 - 2.0 * r)
        out: FloatArray = broad + detail * m * ramp + rough - self._datum_m
        return out

    def _fields(self) -> tuple[FractalNoise, ...]:
        return (self.broad, self.detail, self.mask, self.rough)

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        return self._combine(x, y, *(f.at(x, y) for f in self._fields()))

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        x, y = grid_axes(i0, j0, n, spacing_m)
        return self._combine(x, y, *(f.grid(i0, j0, n, spacing_m) for f in self._fields()))


class RipplePlainsGround:
    """Meridiani ground: gentle undulation + aeolian ripples + centimetre roughness.

    Ripples: ``A(x,y) · ((1 + cos φ) / 2)^1.5`` (peaked crests, broad troughs) with phase
    ``φ = 2π (p · ŵ) / λ + ψ(x, y)``: ``ŵ`` the wind direction (seeded azimuth), crest
    spacing ``λ = WAVELENGTH_M``, ``ψ`` a smooth noise that bends the crests (sinuosity) and
    ``A`` a crest height ``CREST_HEIGHT_M`` modulated by ±40 % over tens of metres.
    Values approximate, after the Meridiani plains ripples seen by Opportunity (crest
    spacing a few metres, heights a few cm; Sullivan et al. 2005).
    """

    WAVELENGTH_M = 4.0
    CREST_HEIGHT_M = 0.05

    def __init__(self, seed: int) -> None:
        self.swell = FractalNoise(seed, 11, [128.0, 64.0, 32.0], [0.3, 0.15, 0.08])
        self.bend = FractalNoise(seed, 12, [24.0, 10.0], [1.2, 0.5])  # radians of phase
        self.strength = FractalNoise(seed, 13, [30.0], [1.0])
        self.rough = FractalNoise(seed, 14, [1.0, 0.5, 0.25], [0.006, 0.004, 0.002])
        u = lattice_uniform(derive_key(seed, 15), np.array([0]), np.array([0]))
        self.wind_azimuth_rad = float(0.5 * np.pi * (u[0] + 1.0))  # uniform in [0, π)
        self._datum_m = 0.0
        self._datum_m = float(self.at(0.0, 0.0))  # elevations relative to the Site origin

    def _combine(
        self,
        x: FloatArray,
        y: FloatArray,
        swell: FloatArray,
        bend: FloatArray,
        strength: FloatArray,
        rough: FloatArray,
    ) -> FloatArray:
        c, s = np.cos(self.wind_azimuth_rad), np.sin(self.wind_azimuth_rad)
        phase = 2.0 * np.pi * (c * x + s * y) / self.WAVELENGTH_M + bend
        amp = self.CREST_HEIGHT_M * (1.0 + 0.4 * np.clip(2.0 * strength, -1.0, 1.0))
        ripple = amp * (0.5 * (1.0 + np.cos(phase))) ** 1.5
        out: FloatArray = swell + ripple + rough - self._datum_m
        return out

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        fields = (f.at(x, y) for f in (self.swell, self.bend, self.strength, self.rough))
        return self._combine(x, y, *fields)

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        x, y = grid_axes(i0, j0, n, spacing_m)
        fields = (
            f.grid(i0, j0, n, spacing_m) for f in (self.swell, self.bend, self.strength, self.rough)
        )
        return self._combine(x, y, *fields)


class TexturedTerrain:
    """An analytic terrain (``FlatTerrain``, ``Eq22Terrain``) with a procedural albedo."""

    def __init__(self, base: FlatTerrain | Eq22Terrain, texture: AlbedoTexture) -> None:
        self.base = base
        self.name = base.name
        self.soil = base.soil
        self.texture = texture

    def height_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        return self.base.height_m(x_m, y_m)

    def gradient(self, x_m: ArrayLike, y_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        return self.base.gradient(x_m, y_m)

    def albedo(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        return self.texture.evaluate(x_m, y_m)


def make_terrain(name: str, seed: int) -> Terrain:
    """Build site ``name``'s terrain, deterministic from ``seed`` (an int in [0, 2**63)).

    Raises InputError('site', ...) for an unknown name, InputError('seed', ...) for a bad
    seed. ``gusev`` and ``meridiani`` are ``HeightmapTerrain``s (unlimited extent, tiles
    built on demand); ``eq22`` and ``flat`` are the analytic surfaces with a texture; a
    scenario place (``sim.world.places``) builds its own.

    >>> t = make_terrain("flat", 0)
    >>> float(t.height_m(3.0, -2.0)), t.soil.name
    (0.0, 'bedrock')
    """
    where = site(name)
    s = _check_seed(seed)
    if name in PLACES:  # on Meridiani: its plains and their look
        return make_place_terrain(name, s, RipplePlainsGround(s), MERIDIANI_ALBEDO)
    if name == "flat":
        return TexturedTerrain(FlatTerrain(), AlbedoTexture(s, ANALYTIC_ALBEDO))
    if name == "eq22":
        return TexturedTerrain(Eq22Terrain(), AlbedoTexture(s, ANALYTIC_ALBEDO))
    if name == "gusev":
        hills = ColumbiaHillsGround(s)
        rocks = RockField(s, RockPopulation(GUSEV_ROCK_ABUNDANCE), ground=hills)
        return HeightmapTerrain(
            "gusev", where.soil, hills, AlbedoTexture(s, GUSEV_ALBEDO), stamp=rocks.stamp
        )
    plains = RipplePlainsGround(s)
    rocks = RockField(s, RockPopulation(MERIDIANI_ROCK_ABUNDANCE, d_max_m=0.5), ground=plains)
    return HeightmapTerrain(
        "meridiani", where.soil, plains, AlbedoTexture(s, MERIDIANI_ALBEDO), stamp=rocks.stamp
    )
