"""The rover's tilt along each drive's nominal path on the ground's terrain map.

``sequences.drive_safety`` walks the nominal paths (no slip, no estimate error) from the
rover's reported pose; with a map in the context (``ValidationContext.terrain``, a
``sequences.terrain_grid.TerrainGrid``) it hands each drive to ``TiltCheck``, which samples
the path (every ``SAMPLE_M`` along straights and arcs, every ``TURN_SAMPLE_DEG`` of a turn in
place or a DRIVE_TO's first turn), sets the rover down there and compares its attitude with
the tilt limit the rover holds (``estimation.protection.limits``: ``tilt_limit_rad``, 30 deg
by default; the limit the rover reports it was set to, and any ``SET_PARAM
param=mobility.tilt_limit_rad`` earlier in the sequence).

**The rover set down on the map**: the rocker-bogie keeps its six wheels on the ground, so
the body takes about the attitude of the plane through the wheels' contact points. As MER's
terrain assessment did for rover-sized patches of its stereo maps (GESTALT, Goldberg,
Maimone and Matthies 2002: a plane fitted to each rover-sized patch, its tilt a hazard), the
heights ``h_i`` under the six wheel centres (``estimation.geometry.FLIGHT_GEOMETRY``,
bilinear on the map) are fitted by least squares with ``h = a + s_x x_i + s_y y_i`` in the
body's horizontal axes (``x`` forward, ``y`` right). The body's x axis lies along the plane
above the heading and its z axis along the plane's normal (down), so the accelerometers at
rest read the specific force ``f = g (s_x/m, s_y/(k m), -1/k)`` with ``m = √(1+s_x²)``,
``k = √(1+s_x²+s_y²)``, and the onboard levelling relations (``estimation.protection.
attitude_limits``, Titterton and Weston 2004) give::

    pitch = atan(s_x)                     (nose up positive)
    roll  = -atan(s_y / √(1 + s_x²))      (right side down positive)

The rover halts when ``max(|roll|, |pitch|)`` exceeds its limit (``estimation.protection.
monitor``): the same test here.

**The warnings** (with the drive's line, the tilt, roll and pitch, where along the drive,
metres from its start or the heading of a turn, and the map's uncertainty there: the height
1σ of the cells under the rover and whether stereo measured them or the orbital DEM alone
has them):

- ``tilt-limit``: the first place the tilt exceeds the limit; the drive will halt there, so
  the drives after it are warned ``drive-after-halt`` as after any drive that may halt;
- ``tilt-near-limit``: a drive that stays under the limit but comes within
  ``NEAR_LIMIT_DEG`` (3 deg, a documented choice: about the tilt a 0.1 m rock under one
  front wheel adds over the 1.4 m wheelbase, which the map does not resolve) of it, at its
  highest tilt.

What the check cannot see: relief the map does not resolve (the orbital DEM's 1 m posts are
smoothed to a few metres by the server, ``server.validation.terrain``; rocks under a wheel),
slip, and the suspension's own angles. Where the path leaves the map, or without a map (no
ground map for the rover yet, or no reported pose) the check is silent.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from estimation.geometry import FLIGHT_GEOMETRY
from sequences import commands as cmd
from sequences.model import SequenceStep
from sequences.terrain_grid import TerrainGrid

FloatArray = NDArray[np.float64]
Warn = Callable[[SequenceStep, str, str], None]

SAMPLE_M = 0.25  # along a drive: half the server's 0.5 m cell
TURN_SAMPLE_DEG = 5.0  # of a turn: the front wheels move 5 cm
NEAR_LIMIT_DEG = 3.0  # ``tilt-near-limit``'s margin (module docstring)

_WHEEL_XY_B = FLIGHT_GEOMETRY.wheel_xy_b()  # (6, 2): x forward, y right
_FIT = np.linalg.pinv(np.column_stack([np.ones(6), _WHEEL_XY_B]))  # (3, 6): a, s_x, s_y
_REACH_M = float(np.max(np.hypot(*_WHEEL_XY_B.T)))  # the farthest wheel from the origin
# |s_x|, |s_y| <= _SLOPE_GAIN * the gradient's bound (TiltCheck): 1.36 for MER's wheels
_SLOPE_GAIN = float(np.max(np.abs(_FIT[1:]) @ np.hypot(*_WHEEL_XY_B.T)))


@dataclass(frozen=True)
class PathSamples:
    """Poses along a drive's nominal path, Site frame: ``north_m``, ``east_m``, ``heading_rad``
    (from North towards East), ``along_m`` the path length from the drive's start, ``turning``
    the samples of a turn in place (where along it is said by the heading)."""

    north_m: FloatArray
    east_m: FloatArray
    heading_rad: FloatArray
    along_m: FloatArray
    turning: NDArray[np.bool_]


def _turn(x: float, y: float, h: float, angle: float) -> PathSamples:
    n = max(2, math.ceil(abs(math.degrees(angle)) / TURN_SAMPLE_DEG) + 1)
    heading = h + np.linspace(0.0, angle, n)
    return PathSamples(np.full(n, x), np.full(n, y), heading, np.zeros(n), np.ones(n, dtype=bool))


def _straight(x: float, y: float, h: float, d: float) -> PathSamples:
    s = np.linspace(0.0, d, max(2, math.ceil(abs(d) / SAMPLE_M) + 1))
    return PathSamples(
        x + s * math.cos(h),
        y + s * math.sin(h),
        np.full(len(s), h),
        s,
        np.zeros(len(s), dtype=bool),
    )


def nominal_samples(c: Any, x: float, y: float, h: float) -> PathSamples:
    """Poses along drive ``c``'s nominal path from ``(x, y)`` heading ``h`` (module
    docstring): an arc of signed radius (> 0 centre on the right) turns the heading by its
    angle clockwise or anticlockwise as ``sequences.drive_safety`` draws it; a DRIVE_TO turns
    in place the shorter way towards its goal, then drives straight.

    >>> s = nominal_samples(cmd.DriveArc(radius_m=2.0, angle_deg=90.0), 0.0, 0.0, 0.0)
    >>> [round(float(v), 6) for v in (s.north_m[-1], s.east_m[-1], s.along_m[-1])]
    [2.0, 2.0, 3.141593]
    """
    if isinstance(c, cmd.DriveStraight):
        return _straight(x, y, h, float(c.distance_m))
    if isinstance(c, cmd.TurnInPlace):
        return _turn(x, y, h, math.radians(float(c.angle_deg)))
    if isinstance(c, cmd.DriveArc):
        r, a = float(c.radius_m), math.radians(float(c.angle_deg))
        sign = 1.0 if r > 0 else -1.0
        length = abs(r) * a
        s = np.linspace(0.0, length, max(2, math.ceil(length / SAMPLE_M) + 1))
        cx, cy = (
            x + abs(r) * math.cos(h + sign * math.pi / 2),
            y + abs(r) * math.sin(h + sign * math.pi / 2),
        )
        start = math.atan2(y - cy, x - cx)
        ang = start + sign * s / abs(r)
        return PathSamples(
            cx + abs(r) * np.cos(ang),
            cy + abs(r) * np.sin(ang),
            h + sign * s / abs(r),
            s,
            np.zeros(len(s), dtype=bool),
        )
    assert isinstance(c, cmd.DriveTo)
    dx, dy = float(c.x_m) - x, float(c.y_m) - y
    bearing = math.atan2(dy, dx) if (dx, dy) != (0.0, 0.0) else h
    turn = _turn(x, y, h, math.remainder(bearing - h, 2.0 * math.pi))
    ahead = _straight(x, y, bearing, math.hypot(dx, dy))
    return PathSamples(
        *(
            np.concatenate([getattr(turn, f), getattr(ahead, f)])
            for f in ("north_m", "east_m", "heading_rad", "along_m", "turning")
        )
    )


def _wheels(
    north_m: FloatArray, east_m: FloatArray, heading_rad: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The six wheels' centres (K, 6), North and East, of the rover at the poses."""
    c, s = np.cos(heading_rad)[:, None], np.sin(heading_rad)[:, None]
    wx, wy = _WHEEL_XY_B[:, 0][None, :], _WHEEL_XY_B[:, 1][None, :]
    wn = np.asarray(north_m)[:, None] + wx * c - wy * s  # body x (c, s), y (-s, c) in N, E
    we = np.asarray(east_m)[:, None] + wx * s + wy * c
    return wn, we


def _gradient_bound(grid: TerrainGrid) -> FloatArray:
    """Per cell (ny - 1, nx - 1), a bound on the gradient of the bilinear surface inside it:
    its North derivative lies between the cell's two North edges' differences over the
    cell, its East one between the two East edges'."""
    h = np.asarray(grid.height_m, dtype=np.float64)
    dn = np.abs(np.diff(h, axis=0)) / grid.cell_m  # (ny - 1, nx)
    de = np.abs(np.diff(h, axis=1)) / grid.cell_m  # (ny, nx - 1)
    out: FloatArray = np.hypot(np.maximum(dn[:, :-1], dn[:, 1:]), np.maximum(de[:-1], de[1:]))
    return out


def footprint_attitude(
    grid: TerrainGrid, north_m: FloatArray, east_m: FloatArray, heading_rad: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Roll and pitch (rad) of the rover set down on ``grid`` at mission-frame poses (module
    docstring), NaN where a wheel is off the map."""
    heights = grid.height_at(*_wheels(north_m, east_m, heading_rad))  # (K, 6)
    coeffs = heights @ _FIT.T  # (K, 3): a, s_x, s_y
    sx, sy = coeffs[:, 1], coeffs[:, 2]
    return -np.arctan(sy / np.sqrt(1.0 + sx * sx)), np.arctan(sx)


def footprint_map(grid: TerrainGrid, north_m: float, east_m: float, heading_rad: float) -> str:
    """What the map knows under the rover's wheels at one pose: their cells' mean height 1σ,
    and whether stereo measured them or the orbital DEM alone has them."""
    wn, we = _wheels(np.array([north_m]), np.array([east_m]), np.array([heading_rad]))
    sigma = float(np.mean(grid.sigma_at(wn, we)))
    imaged = float(np.mean(grid.imaged_at(wn, we)))
    words = f"the map's height 1σ there is {sigma:.2f} m"
    if imaged <= 0.0:
        return f"{words}, the orbital DEM only (no stereo pair has imaged it)"
    if imaged < 1.0:
        return f"{words}, partly from the rover's stereo, partly the orbital DEM only"
    return f"{words}, from the rover's stereo"


@dataclass
class TiltCheck:
    """The check of the module docstring, called by ``sequences.drive_safety`` per drive.

    A drive over gentle ground is passed without setting the rover down at each sample: the
    plane's slopes are weighted sums of the wheels' heights, ``s = Σ P_i h_i`` with
    ``Σ P_i = 0``, so ``|s| ≤ Σ |P_i| r_i · G`` where ``r_i`` is a wheel's distance from the
    rover's origin and ``G`` bounds the map's gradient there (``_gradient_bound``); when
    ``atan`` of that stays under the near-limit threshold, neither warning can be given."""

    warn: Warn
    grid: TerrainGrid
    gradient: FloatArray  # per cell, a bound on the bilinear surface's gradient

    @classmethod
    def start(cls, warn: Warn, context: Any) -> TiltCheck | None:
        """From a ``ValidationContext``: ``None`` when it has no map (the check is silent)."""
        grid = getattr(context, "terrain", None)
        if not isinstance(grid, TerrainGrid):
            return None
        return cls(warn, grid, _gradient_bound(grid))

    def drive(
        self,
        step: SequenceStep,
        c: Any,
        pose: tuple[float, float, float],
        site_offset_m: tuple[float, float],
        limit_rad: float,
    ) -> str | None:
        """Warn about drive ``c`` from ``pose`` (North, East in the current Site, heading),
        the current Site's origin ``site_offset_m`` from the context's Site; the reason the
        drive may halt (for ``drive-after-halt``), or ``None``."""
        x, y, h = pose
        samples = nominal_samples(c, x, y, h)
        on, oe = self.grid.site_origin_m
        north = samples.north_m + on + site_offset_m[0]
        east = samples.east_m + oe + site_offset_m[1]
        grid = self.grid
        ny, nx = grid.shape
        i_lo = math.floor((float(north.min()) - _REACH_M - grid.north0_m) / grid.cell_m)
        i_hi = math.ceil((float(north.max()) + _REACH_M - grid.north0_m) / grid.cell_m)
        j_lo = math.floor((float(east.min()) - _REACH_M - grid.east0_m) / grid.cell_m)
        j_hi = math.ceil((float(east.max()) + _REACH_M - grid.east0_m) / grid.cell_m)
        if i_hi < 0 or j_hi < 0 or i_lo > ny - 1 or j_lo > nx - 1:
            return None  # off the map
        under = self.gradient[max(i_lo, 0) : i_hi + 1, max(j_lo, 0) : j_hi + 1]
        near_rad = limit_rad - math.radians(NEAR_LIMIT_DEG)
        if under.size and math.atan(_SLOPE_GAIN * float(under.max())) <= near_rad:
            return None  # too gentle to come near the limit (class docstring)
        roll, pitch = footprint_attitude(grid, north, east, samples.heading_rad)
        worst = np.maximum(np.abs(roll), np.abs(pitch))
        known = np.flatnonzero(np.isfinite(worst))
        if known.size == 0:
            return None  # off the map
        limit_deg = math.degrees(limit_rad)
        over = known[worst[known] > limit_rad]
        top = int(known[np.argmax(worst[known])])
        if over.size:
            k = int(over[0])
            most = ""
            if worst[top] > worst[k] + math.radians(0.05):
                most = f", up to {math.degrees(worst[top]):.1f} deg {_where(samples, top)}"
            self.warn(
                step,
                "tilt-limit",
                f"on the ground's map the nominal path tilts the rover "
                f"{_attitude(roll[k], pitch[k])} {_where(samples, k)}{most}, past its "
                f"tilt limit of {limit_deg:.1f} deg (mobility.tilt_limit_rad): the drive "
                f"will halt there; {self._map(samples, north, east, k)}",
            )
            return "its tilt limit"
        if worst[top] > limit_rad - math.radians(NEAR_LIMIT_DEG):
            self.warn(
                step,
                "tilt-near-limit",
                f"on the ground's map the nominal path tilts the rover up to "
                f"{_attitude(roll[top], pitch[top])} {_where(samples, top)}, within "
                f"{NEAR_LIMIT_DEG:g} deg of its tilt limit of {limit_deg:.1f} deg "
                f"(mobility.tilt_limit_rad); {self._map(samples, north, east, top)}",
            )
        return None

    def _map(self, samples: PathSamples, north: FloatArray, east: FloatArray, k: int) -> str:
        return footprint_map(self.grid, north[k], east[k], samples.heading_rad[k])


def _attitude(roll: float, pitch: float) -> str:
    worst = max(abs(roll), abs(pitch))
    return (
        f"{math.degrees(worst):.1f} deg (roll {math.degrees(roll):.1f}, "
        f"pitch {math.degrees(pitch):.1f})"
    )


def _where(samples: PathSamples, k: int) -> str:
    if samples.turning[k]:
        heading = math.degrees(float(samples.heading_rad[k])) % 360.0
        return f"as it turns, at heading {heading:.0f} deg"
    return f"{float(samples.along_m[k]):.1f} m from the drive's start"
