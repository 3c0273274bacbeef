"""Scenario places: named spots of a site where a hard case happens, selectable like a site.

A place is named ``<site>:<place>``; ``sim.world.sites.site`` and ``make_terrain`` accept
the name, so ``RoverSim``, ``RoverSession``, ``roverops run`` and the benches start there.
The rover is planted at the Site origin, heading North (``yaw_rad = 0``) by default.

- ``meridiani:endurance_slope``: the inner wall of an Endurance-like crater, loose sand
  (``MERIDIANI_SAND``) sloping 17-24°: Opportunity drove into Endurance crater on slopes
  of this order and measured its slip with visual odometry (Cheng, Maimone and Matthies
  2005, sec. 4.1: the sol 304 drive). The crater is a bowl about ``CRATER_CENTRE_M`` to the
  South of the origin: its floor is level within ``FLOOR_M`` of the centre, the wall's
  slope (its tangent) ramps up to 18° over 5 m and rises linearly in tangent to 23° at the
  rim, ``RIM_M`` from the centre, then flattens over 5 m to the plains beyond; with the
  centimetre relief the slope over a rover's length stays within 17-24° on the wall. At
  the origin the wall slopes 20.4° up to the North. Dimensions approximate (Endurance is about
  130 m across and 20 m deep; the wall here rises ~12 m). For visual odometry the slope
  carries centimetre relief and a sand-and-fragments albedo of more contrast than the
  plains (``ENDURANCE_ALBEDO``; Meridiani's plains are darker and more uniform).
- ``meridiani:purgatory_ripple``: the Meridiani plains (``RipplePlainsGround``) with one
  large ripple across the way, ``PURGATORY_HEIGHT_M`` high and ``2 PURGATORY_HALF_WIDTH_M``
  wide, its crest running East-West ``PURGATORY_X_M`` North of the origin, covered by a band
  of ``SAND_TRAP`` (``sim.world.soil_patches``): the Purgatory ripple, about 30 cm tall and
  2.5 m wide, where Opportunity dug its wheels in to the hubs on sol 446 (the MER mission's
  sol reports). A rover driving North bogs down in it. The band has a sharp edge: graded
  in (a rim, ``SoilPatch.rim_m``), the rover would stall on the ripple's flank in the rim
  with its wheels half sunk, since the model has no digging at a stall (a wheel spinning
  in place excavates down to its hub over time); with the edge, the rover stops at the
  ripple's foot sunk to the hubs, and drops by the extra sinkage (~10 cm) within one
  control step as it enters.

Every place's ground passes through elevation 0 at the Site origin, as the sites' do.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.world.albedo import AlbedoStyle, AlbedoTexture, GrainLayer
from sim.world.heightmap import HeightmapTerrain
from sim.world.noise import FractalNoise, GroundField, grid_axes
from sim.world.soil_patches import Band, SoilPatch
from sim.world.terrain import MERIDIANI_SAND, SAND_TRAP, Terrain

FloatArray = NDArray[np.float64]

CRATER_CENTRE_M = 45.0  # the crater's centre is this far South of the origin
FLOOR_M = 25.0  # level floor out to this radius
WALL_FOOT_M = 30.0  # the wall's slope reaches WALL_FOOT_DEG here ...
RIM_M = 62.0  # ... and WALL_TOP_DEG here, the rim
WALL_FOOT_DEG = 18.0
WALL_TOP_DEG = 23.0
PLAINS_M = 67.0  # level plains beyond this radius

PURGATORY_X_M = 4.0  # the ripple's crest, North of the origin
PURGATORY_HALF_WIDTH_M = 1.25  # 2.5 m wide (sol reports, approximate)
PURGATORY_HEIGHT_M = 0.3  # about 30 cm tall (sol reports, approximate)
PURGATORY_LENGTH_M = 40.0  # the crest runs this far, centred on the origin's meridian

ENDURANCE_ALBEDO = AlbedoStyle(
    mean=0.15,
    contrast=0.2,
    beta=0.3,
    grains=(
        GrainLayer(cell_m=0.02, probability=0.2, relative_contrast=0.4),  # outcrop fragments
        GrainLayer(cell_m=0.006, probability=0.35, relative_contrast=-0.35),  # spherules
        GrainLayer(cell_m=0.0015, probability=0.5, relative_contrast=0.1),  # sand grains
    ),
)


class CraterWallGround:
    """An Endurance-like crater wall with centimetre relief (``GroundField``, elevation up, m).

    The slope's tangent ``t(ρ)`` is piecewise linear in the distance ``ρ`` from the centre
    (knots: module docstring), so the elevation ``h(ρ) = ∫ t dρ`` is piecewise quadratic and
    exact; the relief is value noise of octaves 1 m to 0.25 m, amplitudes 1 cm to 3 mm.
    """

    def __init__(self, seed: int) -> None:
        self.centre_m = (-CRATER_CENTRE_M, 0.0)
        self.knots_m = np.array([0.0, FLOOR_M, WALL_FOOT_M, RIM_M, PLAINS_M, 1e7])
        foot, top = np.tan(np.radians([WALL_FOOT_DEG, WALL_TOP_DEG]))
        self.tan = np.array([0.0, 0.0, foot, top, 0.0, 0.0])
        steps = 0.5 * (self.tan[1:] + self.tan[:-1]) * np.diff(self.knots_m)
        self.h_knots_m = np.concatenate([[0.0], np.cumsum(steps)])
        self.rough = FractalNoise(seed, 21, [1.0, 0.5, 0.25], [0.01, 0.006, 0.003])
        self._datum_m = 0.0
        self._datum_m = float(self.at(0.0, 0.0))

    def radius_m(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Distance (m) from the crater's centre."""
        out: FloatArray = np.hypot(
            np.asarray(x_m, float) - self.centre_m[0], np.asarray(y_m, float) - self.centre_m[1]
        )
        return out

    def wall_tan(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        """Tangent of the wall's slope (without the relief) at the points."""
        out: FloatArray = np.interp(self.radius_m(x_m, y_m), self.knots_m, self.tan)
        return out

    def _wall(self, rho: FloatArray) -> FloatArray:
        k = np.clip(np.searchsorted(self.knots_m, rho, side="right") - 1, 0, self.tan.size - 2)
        d = rho - self.knots_m[k]
        slope = (self.tan[k + 1] - self.tan[k]) / np.diff(self.knots_m)[k]
        out: FloatArray = self.h_knots_m[k] + self.tan[k] * d + 0.5 * slope * d * d
        return out

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        out: FloatArray = self._wall(self.radius_m(x, y)) + self.rough.at(x, y) - self._datum_m
        return out

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        x, y = grid_axes(i0, j0, n, spacing_m)
        wall = self._wall(self.radius_m(x, y))
        out: FloatArray = wall + self.rough.grid(i0, j0, n, spacing_m) - self._datum_m
        return out


class RippleGround:
    """A ground field plus one large ripple whose crest runs East-West at ``PURGATORY_X_M``:
    ``H cos²(π (x - x_c) / (2 w))`` within the half-width ``w`` (``GroundField``)."""

    def __init__(self, plains: GroundField) -> None:
        self.plains = plains

    @staticmethod
    def ripple_m(x_m: FloatArray) -> FloatArray:
        """The ripple's height (m) at Site North ``x_m``."""
        u = (x_m - PURGATORY_X_M) / PURGATORY_HALF_WIDTH_M
        out: FloatArray = np.where(
            np.abs(u) < 1.0, PURGATORY_HEIGHT_M * np.cos(0.5 * np.pi * u) ** 2, 0.0
        )
        return out

    def at(self, x_m: ArrayLike, y_m: ArrayLike) -> FloatArray:
        x, y = np.broadcast_arrays(np.asarray(x_m, np.float64), np.asarray(y_m, np.float64))
        out: FloatArray = self.plains.at(x, y) + self.ripple_m(x)
        return out

    def grid(self, i0: int, j0: int, n: int, spacing_m: float) -> FloatArray:
        x, _ = grid_axes(i0, j0, n, spacing_m)
        out: FloatArray = self.plains.grid(i0, j0, n, spacing_m) + self.ripple_m(x)
        return out


@dataclass(frozen=True)
class Place:
    """A scenario place: the ``site`` it is on and what it is."""

    name: str
    site: str
    description: str


PLACES: dict[str, Place] = {
    p.name: p
    for p in (
        Place(
            "meridiani:endurance_slope",
            "meridiani",
            "Endurance-like crater wall: loose sand sloping 17-24°, textured for VO",
        ),
        Place(
            "meridiani:purgatory_ripple",
            "meridiani",
            "Purgatory-like ripple 4 m ahead: deep loose sand where the rover bogs down",
        ),
    )
}
PLACE_NAMES: tuple[str, ...] = tuple(PLACES)


def place_patches(name: str) -> dict[str, SoilPatch]:
    """The soil patches a place lays on its terrain (none for a plain site)."""
    if name == "meridiani:purgatory_ripple":
        half = 0.5 * PURGATORY_LENGTH_M
        band = Band(PURGATORY_X_M, -half, PURGATORY_X_M, half, PURGATORY_HALF_WIDTH_M)
        return {"purgatory": SoilPatch(SAND_TRAP, band)}  # a sharp edge: see the docstring
    return {}


def make_place_terrain(
    name: str, seed: int, plains: GroundField, plains_albedo: AlbedoStyle
) -> Terrain:
    """The terrain of place ``name`` (in ``PLACES``) from a checked ``seed``; ``plains``
    and ``plains_albedo`` are its site's ground and look (``sim.world.sites`` passes them:
    the sites know the places, not the other way round)."""
    if name == "meridiani:endurance_slope":
        wall = CraterWallGround(seed)
        texture = AlbedoTexture(seed, ENDURANCE_ALBEDO)
        return HeightmapTerrain(name, MERIDIANI_SAND, wall, texture)
    if name == "meridiani:purgatory_ripple":
        ground = RippleGround(plains)
        return HeightmapTerrain(name, MERIDIANI_SAND, ground, AlbedoTexture(seed, plains_albedo))
    raise KeyError(name)
