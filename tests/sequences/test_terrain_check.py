"""The validator's tilt check on the ground's map (``sequences.terrain_check``): hand-made maps
whose slopes are known, so where a drive meets the tilt limit follows from geometry alone."""

from __future__ import annotations

import math
import pickle
import re
from typing import Any

import numpy as np
import pytest

from estimation.geometry import FLIGHT_GEOMETRY
from estimation.protection.attitude_limits import tilt_rad
from estimation.protection.limits import LIMITS, replace_limit
from sequences import commands as cmd
from sequences.terrain_check import (
    NEAR_LIMIT_DEG,
    footprint_attitude,
    footprint_map,
    nominal_samples,
)
from sequences.terrain_grid import TerrainGrid
from sequences.validate import CODES, ValidationContext, ValidationResult, validate

SOL_S = 88775.244
CELL_M = 0.5
HALF_M = 40.0
RAMP_DEG = 20.0
HALF_WHEELBASE_M = FLIGHT_GEOMETRY.x_front_m  # 0.7 m: the front wheels ahead of the origin


def _grid(
    heights: Any, origin: tuple[float, float] = (0.0, 0.0), imaged: bool = False
) -> TerrainGrid:
    """A map of ``heights(north, east)`` over ±HALF_M around the Site's origin ``origin``
    (mission frame), 0.3 m 1σ."""
    axis = np.arange(-HALF_M, HALF_M + CELL_M / 2, CELL_M)
    north, east = np.meshgrid(axis + origin[0], axis + origin[1], indexing="ij")
    shape = north.shape
    return TerrainGrid(
        float(axis[0] + origin[0]), float(axis[0] + origin[1]), CELL_M,
        np.asarray(heights(north, east), dtype=np.float32), np.full(shape, 0.3, np.float32),
        np.full(shape, imaged), origin,
    )  # fmt: skip


def _ramp_north(start_m: float, origin: tuple[float, float] = (0.0, 0.0)) -> TerrainGrid:
    """Level, then rising at RAMP_DEG northward from ``start_m`` North of the Site's origin."""
    slope = math.tan(math.radians(RAMP_DEG))
    return _grid(lambda n, e: np.maximum(0.0, n - origin[0] - start_m) * slope, origin)


def _context(terrain: TerrainGrid | None, **changes: Any) -> ValidationContext:
    """Sol 42 at 10:00 LMST, Fine, the rover at its Site's origin heading North."""
    values: dict[str, Any] = {
        "start_t_s": (42 + 10.0 / 24.0) * SOL_S,
        "lmst_h": lambda t: (t % SOL_S) / SOL_S * 24.0,
        "sol": lambda t: int(t // SOL_S),
        "t_s_for": lambda sol, h: (sol + h / 24.0) * SOL_S,
        "earth_elevation_deg": lambda t: 20.0,
        "aqf": "Fine",
        "p_s_est": (0.0, 0.0),
        "heading_rad": 0.0,
        "terrain": terrain,
    }
    values.update(changes)
    return ValidationContext(**values)


def _tilts(result: ValidationResult) -> list[tuple[int, str]]:
    return [(d.line, d.code) for d in result.warnings if d.code.startswith("tilt")]


def _distance_m(message: str) -> float:
    found = re.search(r"([\d.]+) m from the drive's start", message)
    assert found, message
    return float(found[1])


def _limit_deg(deg: float) -> str:
    return f"SET_PARAM param=mobility.tilt_limit_rad value={math.radians(deg)!r}\n"


def test_a_drive_up_a_ramp_steeper_than_the_limit_warns_with_its_line_and_distance() -> None:
    ctx = _context(_ramp_north(5.0))
    text = _limit_deg(15.0) + "WAIT duration_s=5\nDRIVE_STRAIGHT distance_m=10\n"
    text += "DRIVE_STRAIGHT distance_m=1\n"
    result = validate(text, ctx)
    assert result.ok
    assert _tilts(result) == [(3, "tilt-limit"), (4, "tilt-limit")]
    assert [(d.line, d.code) for d in result.warnings if d.code == "drive-after-halt"] == [
        (4, "drive-after-halt")
    ]
    first = result.warnings[0].message
    # the plane through the wheels passes 15 deg between the front wheels reaching the ramp's
    # foot and the rear ones reaching it; once all six are on it, it is the ramp's 20 deg
    assert 5.0 - HALF_WHEELBASE_M <= _distance_m(first) <= 5.0 + HALF_WHEELBASE_M
    assert "up to 20.0 deg" in first and "limit of 15.0 deg" in first
    after = [d.message for d in result.warnings if d.code == "drive-after-halt"]
    assert "line 3's drive, which may halt on its tilt limit" in after[0]
    assert "orbital DEM only" in first and "0.30 m" in first
    # the rover's own limit (30 deg) is not reached, but within the margin of it below
    assert _tilts(validate("DRIVE_STRAIGHT distance_m=10\n", ctx)) == []
    below = _limit_deg(RAMP_DEG + NEAR_LIMIT_DEG - 0.5)
    near = validate(below + "DRIVE_STRAIGHT distance_m=10\n", ctx)
    assert _tilts(near) == [(2, "tilt-near-limit")]
    assert "up to 20.0 deg" in near.warnings[0].message


def test_the_limit_the_rover_reports_holding_is_the_one_checked() -> None:
    reported = replace_limit(LIMITS, "tilt_limit_rad", math.radians(18.0))
    ctx = _context(_ramp_north(5.0), mobility_limits=reported)
    result = validate("DRIVE_STRAIGHT distance_m=10\n", ctx)
    assert _tilts(result) == [(1, "tilt-limit")]
    assert "limit of 18.0 deg" in result.warnings[0].message


def test_flat_ground_a_map_elsewhere_and_no_map_are_silent() -> None:
    text = _limit_deg(4.0) + "DRIVE_STRAIGHT distance_m=10\nDRIVE_ARC radius_m=2 angle_deg=270\n"
    text += "TURN_IN_PLACE angle_deg=-120\n"
    assert _tilts(validate(text, _context(_grid(lambda n, e: 0.0 * n + 3.0)))) == []
    assert _tilts(validate(text, _context(None))) == []
    far = _ramp_north(5.0, origin=(500.0, 0.0))  # the rover's Site is 500 m from the map's
    assert _tilts(validate(text, _context(far, p_s_est=(-500.0, 0.0)))) == []
    # without a pose there is no path to check
    assert _tilts(validate(text, _context(_ramp_north(0.0), p_s_est=None))) == []


def test_an_arc_onto_a_side_slope_warns_where_it_reaches_it() -> None:
    # ground rising East from 3 m East of the rover: a right arc (centre East) climbs it,
    # a left arc stays on the level
    slope = math.tan(math.radians(RAMP_DEG))
    ctx = _context(_grid(lambda n, e: np.maximum(0.0, e - 3.0) * slope))
    text = _limit_deg(15.0) + "DRIVE_ARC radius_m={r} angle_deg=120\n"
    assert _tilts(validate(text.format(r=-3.0), ctx)) == []
    result = validate(text.format(r=3.0), ctx)
    assert _tilts(result) == [(2, "tilt-limit")]
    # on the arc, s metres along it is 3 - 3 cos(s / 3) East: the rover's footprint (±0.7 m
    # along the heading, ±0.6 m across) first touches the slope at 3 - 0.92 m East
    s = _distance_m(result.warnings[0].message)
    east = 3.0 - 3.0 * math.cos(s / 3.0)
    assert 3.0 - math.hypot(0.7, 0.6) <= east <= 3.0 + math.hypot(0.7, 0.6)


def test_a_turn_in_place_onto_a_slope_warns_by_its_heading() -> None:
    # level to 0.65 m East of the rover, then rising at 40 deg: heading North its wheels
    # (0.6 m either side) are on the level; turning right, its front right wheel swings out
    # to 0.92 m East (at heading 49 deg) and onto the slope
    slope = math.tan(math.radians(40.0))
    ctx = _context(_grid(lambda n, e: np.maximum(0.0, e - 0.65) * slope))
    result = validate(_limit_deg(4.5) + "TURN_IN_PLACE angle_deg=90\n", ctx)
    assert _tilts(result) == [(2, "tilt-limit")]
    found = re.search(r"as it turns, at heading (\d+) deg", result.warnings[0].message)
    assert found and 0 < int(found[1]) < 90


def test_the_site_origin_places_the_path_on_the_map() -> None:
    origin = (120.0, -35.0)  # where the rover's Site lies in the mission frame
    ctx = _context(_ramp_north(5.0, origin=origin))
    result = validate(_limit_deg(15.0) + "DRIVE_STRAIGHT distance_m=10\n", ctx)
    assert _tilts(result) == [(2, "tilt-limit")]
    assert 4.3 <= _distance_m(result.warnings[0].message) <= 5.7
    # from a pose 2 m along, then a new Site planted 1 m further: the ramp's foot is 2 m
    # ahead of the new Site's origin
    planted = validate(
        _limit_deg(15.0) + "DRIVE_STRAIGHT distance_m=1\nPLANT_SITE\nDRIVE_STRAIGHT distance_m=6\n",
        _context(_ramp_north(5.0, origin=origin), p_s_est=(2.0, 0.0)),
    )
    assert _tilts(planted) == [(4, "tilt-limit")]
    assert 2.0 - 0.7 <= _distance_m(planted.warnings[0].message) <= 2.0 + 0.7


def test_the_footprint_on_a_plane_tilts_the_rover_by_the_plane_s_slope_at_any_heading() -> None:
    """Invariant: on a plane of slope θ the body's z axis is the plane's normal, θ from the
    vertical whatever the heading (``tilt_rad`` of the onboard roll and pitch)."""
    theta = math.radians(17.0)
    azimuth = math.radians(35.0)  # the plane rises towards N35E
    gn, ge = math.cos(azimuth) * math.tan(theta), math.sin(azimuth) * math.tan(theta)
    grid = _grid(lambda n, e: gn * n + ge * e)
    headings = np.radians(np.arange(35.0, 395.0, 15.0))  # from straight uphill
    roll, pitch = footprint_attitude(
        grid, np.full(len(headings), 3.0), np.full(len(headings), -2.0), headings
    )
    for r, p in zip(roll, pitch, strict=True):
        assert tilt_rad(float(r), float(p)) == pytest.approx(theta, abs=1e-5)
    up = 0  # heading 35 deg: straight uphill
    assert math.degrees(pitch[up]) == pytest.approx(17.0, abs=1e-3)  # nose up the slope
    assert math.degrees(roll[up]) == pytest.approx(0.0, abs=1e-3)
    right = 18  # heading 305 deg: uphill on its right
    assert roll[right] < 0.0  # the right side up: roll is right side down positive
    assert footprint_map(grid, 3.0, -2.0, 0.0).endswith(
        "the orbital DEM only (no stereo pair has imaged it)"
    )
    assert "1σ there is 0.30 m" in footprint_map(grid, 3.0, -2.0, 0.0)


def test_the_nominal_samples_follow_the_commands() -> None:
    straight = nominal_samples(cmd.DriveStraight(distance_m=3.0), 1.0, 2.0, math.pi / 2)
    assert (straight.north_m[-1], straight.east_m[-1]) == pytest.approx((1.0, 5.0))
    arc = nominal_samples(cmd.DriveArc(radius_m=-4.0, angle_deg=90.0), 0.0, 0.0, 0.0)
    assert (arc.north_m[-1], arc.east_m[-1], arc.heading_rad[-1]) == pytest.approx(
        (4.0, -4.0, -math.pi / 2)
    )
    assert np.allclose(np.hypot(arc.north_m, arc.east_m + 4.0), 4.0)  # on the circle
    to = nominal_samples(cmd.DriveTo(x_m=0.0, y_m=-3.0), 0.0, 0.0, 0.0)
    turned = to.heading_rad[to.turning]
    assert turned[-1] == pytest.approx(-math.pi / 2)
    assert np.all(np.diff(turned) < 0)  # the shorter way: left
    assert to.along_m[-1] == pytest.approx(3.0)


def test_the_codes_and_the_grid_checks() -> None:
    assert CODES["tilt-limit"] == CODES["tilt-near-limit"] == "warning"
    grid = _ramp_north(5.0)
    again = pickle.loads(pickle.dumps(_context(grid).terrain))
    assert np.array_equal(again.height_m, grid.height_m) and again.site_origin_m == (0.0, 0.0)
    flat = np.zeros((3, 3))
    with pytest.raises(ValueError, match="cell_m"):
        TerrainGrid(0.0, 0.0, 0.0, flat, flat, flat > 0, (0.0, 0.0))
    with pytest.raises(ValueError, match="sigma_m"):
        TerrainGrid(0.0, 0.0, 1.0, flat, np.zeros((2, 2)), flat > 0, (0.0, 0.0))
    with pytest.raises(ValueError, match="finite"):
        TerrainGrid(0.0, 0.0, 1.0, flat + np.nan, flat, flat > 0, (0.0, 0.0))
    with pytest.raises(ValueError, match="site_origin_m"):
        TerrainGrid(0.0, 0.0, 1.0, flat, flat, flat > 0, (0.0, math.inf))


def test_the_gentle_ground_shortcut_never_hides_a_tilt() -> None:
    """The bound ``TiltCheck`` skips gentle drives with holds on rough random maps: the
    rover's tilt at a pose never exceeds ``atan`` of the slope gain times the largest
    gradient bound of the cells within a wheel's reach."""
    from sequences.terrain_check import _REACH_M, _SLOPE_GAIN, _gradient_bound

    rng = np.random.default_rng(3)
    for roughness in (0.02, 0.2, 1.0):
        grid = _grid(lambda n, e, s=roughness: rng.normal(0.0, s, n.shape))
        bound = _gradient_bound(grid)
        poses = rng.uniform(-30.0, 30.0, (300, 3))
        roll, pitch = footprint_attitude(grid, *poses.T)
        for (n, e, _), r, p in zip(poses, roll, pitch, strict=True):
            i0 = math.floor((n - _REACH_M - grid.north0_m) / grid.cell_m)
            j0 = math.floor((e - _REACH_M - grid.east0_m) / grid.cell_m)
            i1 = math.ceil((n + _REACH_M - grid.north0_m) / grid.cell_m)
            j1 = math.ceil((e + _REACH_M - grid.east0_m) / grid.cell_m)
            limit = math.atan(_SLOPE_GAIN * float(bound[i0 : i1 + 1, j0 : j1 + 1].max()))
            assert max(abs(r), abs(p)) <= limit + 1e-9
