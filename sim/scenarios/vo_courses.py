"""Courses for the visual-odometry benchmark, found on the sites' own terrain (truth).

- ``find_rock_course``: Cheng, Maimone and Matthies 2005's ground test (sec. 3, Fig. 4) drove "over
several large
  non-obstacle rocks, each less than 20 cm tall". On ``gusev`` we look for a straight
  course whose wheel tracks cross at least ``min_bumps`` rocks, the tallest
  ``ROCK_MIN_M``-``ROCK_MAX_M`` high, with nothing taller than ``ROCK_MAX_M`` anywhere under
  the rover. A rock's height is the terrain's height minus the ground's without rocks
  (``HeightmapTerrain.ground``).
- ``find_slope_course``: a straight course "up and across" a slope of ``slope_deg`` (45 deg
  from the fall line, uphill), where the ground's slope (over a 2 m baseline, rocks
  excluded) stays within ``SLOPE_TOLERANCE_DEG`` of it and averages within 1.5 deg over the
  whole course. Gusev's hills reach 20 deg a few hundred metres from the origin
  (``sim.world.sites``), so the search covers ``SLOPE_SEARCH_M`` around it.

Positions are Site-frame metres (x North, y East); headings clockwise from North, rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage

from sim.errors import InputError
from sim.rover.geometry import MER_GEOMETRY
from sim.world.heightmap import HeightmapTerrain

FloatArray = NDArray[np.float64]

ROCK_MIN_M = 0.08  # the tallest rock under the wheels: a real climb ...
ROCK_MAX_M = 0.20  # ... but a non-obstacle, as in Cheng, Maimone and Matthies 2005 Fig. 4
BUMP_M = 0.04  # a stretch of track this far above the ground is on a rock
TRACK_SAMPLE_M = 0.02
SLOPE_SEARCH_M = 800.0
SLOPE_GRID_M = 4.0
SLOPE_TOLERANCE_DEG = 6.0


@dataclass(frozen=True)
class Course:
    """A straight course from ``(x_m, y_m)`` heading ``yaw_rad``; ``feature_m`` the tallest
    rock under the wheels (rock course) and ``slope_deg`` the ground's mean slope along
    it; ``bumps`` how many rock crossings the wheel tracks make."""

    x_m: float
    y_m: float
    yaw_rad: float
    feature_m: float
    slope_deg: float
    bumps: int


def _relief(terrain: HeightmapTerrain, x: FloatArray, y: FloatArray) -> FloatArray:
    """Height of the rocks above the ground at ``(x, y)``, m."""
    out: FloatArray = terrain.height_m(x, y) - terrain.ground.at(x, y)
    return out


def _strip_relief(
    terrain: HeightmapTerrain,
    x0: float,
    y0: float,
    yaw: float,
    along_m: FloatArray,
    lateral_m: FloatArray,
) -> FloatArray:
    """Rock relief (m) on lines ``lateral_m`` to the right of the course, at ``along_m``
    from its start: (len(lateral_m), len(along_m))."""
    c, sn = math.cos(yaw), math.sin(yaw)
    gx = x0 + along_m[None, :] * c - lateral_m[:, None] * sn
    gy = y0 + along_m[None, :] * sn + lateral_m[:, None] * c
    return _relief(terrain, gx, gy)


def find_rock_course(
    terrain: HeightmapTerrain,
    rng: np.random.Generator,
    length_m: float,
    min_bumps: int = 2,
    place_m: float = 25.0,
    attempts: int = 2000,
) -> Course:
    """A rock course (module docstring) of ``length_m`` of wheel travel, its start drawn
    within ``place_m`` of the origin; InputError if none is found in ``attempts`` draws."""
    if not isinstance(terrain, HeightmapTerrain):
        raise InputError("terrain", "a rock course needs a heightmap site (gusev)")
    half_track = 0.5 * MER_GEOMETRY.track_m
    half_wheel = 0.5 * MER_GEOMETRY.wheel_width_m
    x_front, x_rear = MER_GEOMETRY.x_front_m, -MER_GEOMETRY.x_front_m
    s = np.arange(x_rear, x_front + length_m, TRACK_SAMPLE_M)  # every wheel's ground
    tracks = np.array([side * (half_track + d) for side in (-1, 1) for d in (-half_wheel, 0.0,
                       half_wheel)])  # fmt: skip
    swath = np.linspace(-half_track - half_wheel, half_track + half_wheel, 13)
    for _ in range(attempts):
        x0, y0 = (float(v) for v in rng.uniform(-place_m, place_m, 2))
        yaw = float(rng.uniform(-math.pi, math.pi))
        if float(_strip_relief(terrain, x0, y0, yaw, s, swath).max()) > ROCK_MAX_M:
            continue
        on_tracks = _strip_relief(terrain, x0, y0, yaw, s, tracks)
        tallest = float(on_tracks.max())
        if tallest < ROCK_MIN_M:
            continue
        bumps = sum(int(ndimage.label(row > BUMP_M)[1]) for row in on_tracks[1::3])  # centres
        if bumps >= min_bumps:
            return Course(float(x0), float(y0), yaw, tallest, _mean_slope_deg(terrain, x0, y0,
                          yaw, length_m), bumps)  # fmt: skip
    raise InputError("terrain", f"no rock course found in {attempts} draws")


def _slope_deg(terrain: HeightmapTerrain, x: FloatArray, y: FloatArray, h: float) -> FloatArray:
    g = terrain.ground
    gx = (g.at(x + h, y) - g.at(x - h, y)) / (2.0 * h)
    gy = (g.at(x, y + h) - g.at(x, y - h)) / (2.0 * h)
    out: FloatArray = np.degrees(np.arctan(np.hypot(gx, gy)))
    return out


def _mean_slope_deg(
    terrain: HeightmapTerrain, x0: float, y0: float, yaw: float, length_m: float
) -> float:
    s = np.linspace(0.0, length_m, 21)
    return float(np.mean(_slope_deg(terrain, x0 + s * math.cos(yaw), y0 + s * math.sin(yaw), 1.0)))


def find_slope_course(
    terrain: HeightmapTerrain, rng: np.random.Generator, slope_deg: float, length_m: float
) -> Course:
    """A course up and across a slope of ``slope_deg`` (module docstring), chosen at
    random among the candidates; InputError if the site has none within the search."""
    if not isinstance(terrain, HeightmapTerrain):
        raise InputError("terrain", "a slope course needs a heightmap site (gusev)")
    g = terrain.ground
    axis = np.arange(-SLOPE_SEARCH_M, SLOPE_SEARCH_M, SLOPE_GRID_M)
    X, Y = np.meshgrid(axis, axis, indexing="ij")
    h = 6.0  # the broad slope first (12 m baseline), then the course's own
    gx = (g.at(X + h, Y) - g.at(X - h, Y)) / (2.0 * h)
    gy = (g.at(X, Y + h) - g.at(X, Y - h)) / (2.0 * h)
    broad = np.degrees(np.arctan(np.hypot(gx, gy)))
    candidates = np.argwhere(np.abs(broad - slope_deg) < 1.5)
    s = np.linspace(0.0, length_m, 41)
    for i, j in rng.permutation(candidates):
        uphill = math.atan2(float(gy[i, j]), float(gx[i, j]))  # elevation up: towards +grad
        for side in rng.permutation([1.0, -1.0]):
            yaw = uphill + side * math.pi / 4.0
            x, y = X[i, j] + s * math.cos(yaw), Y[i, j] + s * math.sin(yaw)
            along = _slope_deg(terrain, x, y, 1.0)
            if (
                np.all(np.abs(along - slope_deg) <= SLOPE_TOLERANCE_DEG)
                and abs(float(along.mean()) - slope_deg) <= 1.5
            ):
                yaw = (yaw + math.pi) % (2.0 * math.pi) - math.pi
                return Course(
                    float(X[i, j]), float(Y[i, j]), float(yaw), 0.0, float(along.mean()), 0
                )
    raise InputError("terrain", f"no {slope_deg:g} deg slope within {SLOPE_SEARCH_M:g} m")
