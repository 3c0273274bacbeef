"""The ground's checks of drives against mobility fault protection: a nominal path across a
keep-out zone (the rover's, or one the sequence adds), the drives after one that may halt,
a timeout or time-of-day limit the drive will reach, and the mobility commands' own checks."""

from __future__ import annotations

import math
import re
from typing import Any

import pytest

from estimation.protection.keepout import KeepOutZone
from sequences import commands as cmd
from sequences.validate import ValidationContext, ValidationResult, validate

SOL_S = 88775.244


def _lmst_h(t_s: float) -> float:
    return (t_s % SOL_S) / SOL_S * 24.0


def _context(**changes: Any) -> ValidationContext:
    """Sol 42 at 10:00 LMST, Fine, the rover at the Site's origin heading North."""
    values: dict[str, Any] = {
        "start_t_s": (42 + 10.0 / 24.0) * SOL_S,
        "lmst_h": _lmst_h,
        "sol": lambda t: int(t // SOL_S),
        "t_s_for": lambda sol, h: (sol + h / 24.0) * SOL_S,
        "earth_elevation_deg": lambda t: 20.0,
        "aqf": "Fine",
        "p_s_est": (0.0, 0.0),
        "heading_rad": 0.0,
    }
    values.update(changes)
    return ValidationContext(**values)


def _codes(result: ValidationResult) -> list[tuple[int, str]]:
    return [(d.line, d.code) for d in result.warnings]


def test_a_path_across_a_zone_the_sequence_adds_is_warned_with_its_line() -> None:
    text = (
        "KEEPOUT_ADD zone=wopmay x_m=4 y_m=0.3 radius_m=1\n"
        "DRIVE_STRAIGHT distance_m=6\n"
        "DRIVE_STRAIGHT distance_m=1\n"
        "CLEAR_MOBILITY_FAULT\n"
        "DRIVE_ARC radius_m=5 angle_deg=30\n"
    )
    result = validate(text, _context())
    assert result.ok
    assert _codes(result) == [(2, "keepout-crossing"), (3, "drive-after-halt")]
    crossing = result.warnings[0].message
    assert "wopmay" in crossing and "added at line 1" in crossing
    assert "line 2's drive" in result.warnings[1].message


def test_a_zone_the_rover_holds_and_the_nominal_path_turning_into_it() -> None:
    zone = KeepOutZone.circle("dune", 0, 0.0, 5.0, 1.0)  # East of the rover
    ctx = _context(keepout_zones=(zone,))
    assert _codes(validate("DRIVE_STRAIGHT distance_m=5\n", ctx)) == []
    warned = validate("TURN_IN_PLACE angle_deg=90\nDRIVE_STRAIGHT distance_m=5\n", ctx)
    assert _codes(warned) == [(2, "keepout-crossing")]
    assert "held by the rover" in warned.warnings[0].message
    # an arc to the right bends into it, one to the left away from it
    assert _codes(validate("DRIVE_ARC radius_m=2.5 angle_deg=180\n", ctx)) == [
        (1, "keepout-crossing")
    ]
    assert _codes(validate("DRIVE_ARC radius_m=-2.5 angle_deg=180\n", ctx)) == []
    # a cleared zone is no longer in the way
    cleared = validate(
        "KEEPOUT_CLEAR zone=all\nTURN_IN_PLACE angle_deg=90\nDRIVE_STRAIGHT distance_m=5\n", ctx
    )
    assert _codes(cleared) == []


def test_a_zone_in_an_earlier_site_is_checked_after_planting() -> None:
    text = (
        'KEEPOUT_ADD zone=rock polygon_m="7,-1 9,-1 9,1 7,1"\n'
        "DRIVE_STRAIGHT distance_m=5\n"
        "PLANT_SITE\n"
        "DRIVE_STRAIGHT distance_m=4\n"
    )
    assert _codes(validate(text, _context())) == [(4, "keepout-crossing")]


def test_time_limits_the_drive_will_reach_and_a_rover_already_halted() -> None:
    text = "DRIVE_STRAIGHT distance_m=3 timeout_s=30\nDRIVE_STRAIGHT distance_m=1\n"
    assert _codes(validate(text, _context())) == [(1, "drive-timeout"), (2, "drive-after-halt")]
    late = "DRIVE_STRAIGHT distance_m=3 lmst_limit_h=10.01\n"
    assert _codes(validate(late, _context())) == [(1, "lmst-limit")]
    assert _codes(validate("DRIVE_STRAIGHT distance_m=3 lmst_limit_h=11\n", _context())) == []
    halted = _context(mobility_fault="slip check: slip 44.5 % over 5.00 m > limit 40 %")
    result = validate("DRIVE_STRAIGHT distance_m=1\n", halted)
    assert _codes(result) == [(1, "drive-after-halt")]
    assert "44.5 %" in result.warnings[0].message
    assert _codes(validate("CLEAR_MOBILITY_FAULT\nDRIVE_STRAIGHT distance_m=1\n", halted)) == []


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("KEEPOUT_ADD zone=a x_m=1 y_m=2\n", "a circle needs all three"),
        ('KEEPOUT_ADD zone=a x_m=1 y_m=2 radius_m=1 polygon_m="0,0 1,0 0,1"\n', "not both"),
        ('KEEPOUT_ADD zone=a polygon_m="0,0 1,1"\n', "at least 3"),
        ("KEEPOUT_ADD zone=all x_m=1 y_m=2 radius_m=1\n", "zone"),
        ('KEEPOUT_CLEAR zone="no such!"\n', "zone"),
        ("SET_PARAM param=mobility.slip_limit value=1.5\n", r"mobility\.slip_limit"),
        ("SET_PARAM param=mobility.warp value=1\n", "no such limit"),
        ("DRIVE_STRAIGHT distance_m=1 vo_fail=maybe\n", "vo_fail"),
        ("DRIVE_STRAIGHT distance_m=1 slip_limit_pct=140\n", "slip_limit_pct"),
        ("DRIVE_STRAIGHT distance_m=1 lmst_limit_h=25\n", "lmst_limit_h"),
    ],
)
def test_the_mobility_commands_arguments_are_checked(text: str, match: str) -> None:
    result = validate(text)
    assert not result.ok
    assert any(re.search(match, d.message) for d in result.errors), result.errors


def test_the_mobility_commands_round_trip() -> None:
    c = cmd.DriveStraight(distance_m=6.0, vo=True, slip_limit_pct=40.0, vo_fail="continue")
    assert (
        c.describe() == "DRIVE_STRAIGHT distance_m=6.0 vo=true slip_limit_pct=40.0 vo_fail=continue"
    )
    assert math.isclose(float(cmd.KeepoutAdd(zone="w", x_m=1, y_m=2, radius_m=3).radius_m or 0), 3)


def _entered_m(message: str) -> float:
    found = re.search(r"entering it ([\d.]+) m from the drive's start", message)
    assert found, message
    return float(found[1])


def test_a_crossing_says_where_along_the_drive_the_path_enters_the_zone() -> None:
    zone = KeepOutZone.circle("dune", 0, 4.0, 0.3, 1.0)
    straight = validate("DRIVE_STRAIGHT distance_m=6\n", _context(keepout_zones=(zone,)))
    assert _entered_m(straight.warnings[0].message) == pytest.approx(
        4.0 - math.sqrt(0.91), abs=0.01
    )
    # along an arc: the zone's centre on the arc's end, 2.5 m radius: the chord to the
    # entry point is 1 m, so the path enters it 2 asin(0.2) short of its half turn
    ctx = _context(keepout_zones=(KeepOutZone.circle("dune", 0, 0.0, 5.0, 1.0),))
    arc = validate("DRIVE_ARC radius_m=2.5 angle_deg=180\n", ctx)
    expected = 2.5 * (math.pi - 2.0 * math.asin(0.2))
    assert _entered_m(arc.warnings[0].message) == pytest.approx(expected, abs=0.02)
    # a polygon after a turn: the drive East from 1 m North enters its West edge at 3 m East
    square = KeepOutZone.polygon("rock", 0, [(0.0, 3.0), (2.0, 3.0), (2.0, 5.0), (0.0, 5.0)])
    turned = validate(
        "TURN_IN_PLACE angle_deg=90\nDRIVE_STRAIGHT distance_m=6\n",
        _context(keepout_zones=(square,), p_s_est=(1.0, 0.0)),
    )
    assert [(d.line, d.code) for d in turned.warnings] == [(2, "keepout-crossing")]
    assert _entered_m(turned.warnings[0].message) == pytest.approx(3.0, abs=0.01)
    assert "at (1.0, 3.0) m in Site 0" in turned.warnings[0].message
