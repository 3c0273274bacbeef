"""Typed commands (``sequences.commands``): every argument is checked at construction.

For each command: good values (including the edges of each range) are accepted and kept;
out-of-range values, NaN, infinities, booleans passed as numbers and wrong types raise
``ValueError`` naming the argument. Ranges are those the command dictionary documents.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import pytest

from sequences import commands as cmd

BAD_NUMBERS: list[object] = [math.nan, math.inf, -math.inf, True, False, "1.0", None, [1.0]]

# (command class, argument, accepted values, refused in-type values, extra fixed arguments)
NUMERIC: list[tuple[type[cmd.Command], str, list[float], list[float], dict[str, Any]]] = [
    (cmd.DriveStraight, "distance_m", [0.01, 2, 100.0], [0.0, -1.0, 100.001], {}),
    (cmd.DriveArc, "radius_m", [0.6, -0.6, 3.5, -20.0, 1000.0], [0.0, 0.59, -0.5, 1000.1],
     {"angle_deg": 1.0}),
    (cmd.DriveArc, "angle_deg", [0.1, 90, 360.0], [0.0, -10.0, 360.5], {"radius_m": 2.0}),
    (cmd.TurnInPlace, "angle_deg", [-360.0, -0.5, 0.5, 90, 360.0], [0.0, -360.1, 361.0], {}),
    (cmd.NadirUpdate, "window_s", [0.125, 10, 600.0], [0.0, -1.0, 600.5], {}),
    (cmd.NadirCheck, "tolerance_deg", [0.01, 1, 90.0], [0.0, -1.0, 90.5], {}),
    (cmd.NadirCheck, "window_s", [0.125, 10, 600.0], [0.0, 601.0], {}),
    (cmd.Suncheck, "tolerance_deg", [0.01, 2, 90.0], [0.0, -2.0, 200.0], {}),
    (cmd.Gyrocompass, "duration_s", [1.0, 1800, 21600.0], [0.0, -1.0, 21600.5], {}),
    (cmd.HgaPass, "duration_min", [0.5, 5, 15.0, 120.0], [0.0, -5.0, 120.5], {}),
    (cmd.Wait, "duration_s", [0.001, 60, 177550.488], [0.0, -1.0, 177551.0], {}),
]  # fmt: skip
NUMERIC_IDS = [f"{c.__name__}.{arg}" for c, arg, *_ in NUMERIC]


@pytest.mark.parametrize(("kind", "arg", "good", "bad", "extra"), NUMERIC, ids=NUMERIC_IDS)
def test_numeric_arguments_accept_their_range_and_refuse_the_rest(
    kind: type[cmd.Command],
    arg: str,
    good: list[float],
    bad: list[float],
    extra: dict[str, Any],
) -> None:
    make: Callable[..., cmd.Command] = kind
    for value in good:
        c = make(**extra, **{arg: value})
        assert getattr(c, arg) == value and c.arguments()[arg] == value
        assert c.describe().startswith(kind.name)
        assert f"{arg}={value}" in c.describe()
    optional = kind.__dataclass_fields__[arg].default is None  # None: use the parameter
    for value in [*bad, *BAD_NUMBERS]:
        if value is None and optional:
            assert getattr(make(**extra, **{arg: value}), arg) is None
            continue
        with pytest.raises(ValueError, match=f"^{arg}: "):
            make(**extra, **{arg: value})


def test_an_arc_longer_than_one_drive_is_refused() -> None:
    assert cmd.DriveArc(radius_m=-50.0, angle_deg=114.0).angle_deg == 114.0  # 99.5 m
    with pytest.raises(ValueError, match=r"^angle_deg: the arc would be longer than 100 m"):
        cmd.DriveArc(radius_m=-50.0, angle_deg=115.0)  # 100.4 m
    with pytest.raises(ValueError, match=r"^angle_deg: "):
        cmd.DriveArc(radius_m=20.0, angle_deg=300.0)  # 104.7 m


def test_optional_arguments_default_to_the_parameter() -> None:
    for kind in (cmd.NadirUpdate, cmd.NadirCheck, cmd.Suncheck, cmd.Gyrocompass, cmd.Sungaze):
        c = kind()
        assert all(v is None for v in c.arguments().values())
        assert c.describe() == kind.name
    assert cmd.HgaPass().duration_min == 15.0


def test_sungaze_use_gravity_takes_only_a_bool() -> None:
    assert cmd.Sungaze(use_gravity=True).use_gravity is True
    assert cmd.Sungaze(use_gravity=False).describe() == "SUNGAZE use_gravity=false"
    for value in (1, 0, "yes", "true", 1.0, math.nan):
        with pytest.raises(ValueError, match=r"^use_gravity: "):
            cmd.Sungaze(use_gravity=value)  # type: ignore[arg-type]


def test_set_param_checks_the_name_and_the_value() -> None:
    c = cmd.SetParam(param="sungaze.timer_s", value=300.0)
    assert c.describe() == "SET_PARAM param=sungaze.timer_s value=300.0"
    assert cmd.SetParam(param="sungaze.early_stop", value=False).value is False
    assert cmd.SetParam(param="nadir.min_valid_samples", value=30).value == 30
    assert cmd.SetParam(param="min_sun_elevation_rad", value=-0.05).value == -0.05
    for param in ("", "   ", None, 3, ["sungaze.timer_s"]):
        with pytest.raises(ValueError, match=r"^param: "):
            cmd.SetParam(param=param, value=1.0)  # type: ignore[arg-type]
    for value in (math.nan, math.inf, -math.inf, "300", None, [1.0], {"v": 1}):
        with pytest.raises(ValueError, match=r"^value: "):
            cmd.SetParam(param="sungaze.timer_s", value=value)  # type: ignore[arg-type]


def test_commands_without_arguments() -> None:
    for kind in (
        cmd.PlantSite,
        cmd.Sunfind,
        cmd.GetTiltAttitude,
        cmd.GetCoarseAttitude,
        cmd.GetFineAttitude,
        cmd.SuncheckSungaze,
        cmd.ArticulateStart,
        cmd.ArticulateStop,
    ):
        c = kind()
        assert c.arguments() == {} and c.describe() == kind.name
        with pytest.raises(TypeError):
            kind(1)  # type: ignore[call-arg]


def test_commands_are_immutable_and_the_dictionary_holds_each_once() -> None:
    c = cmd.DriveStraight(distance_m=2.0)
    with pytest.raises(AttributeError):
        c.distance_m = 200.0  # type: ignore[misc]
    assert len(cmd.COMMANDS) == 24
    for name, kind in cmd.COMMANDS.items():
        assert kind.name == name and name.isupper()
    # the keyword is the class name in upper snake case
    for kind in cmd.COMMANDS.values():
        snake = "".join(f"_{ch}" if ch.isupper() else ch for ch in kind.__name__).lstrip("_")
        assert snake.upper() == kind.name


@pytest.mark.parametrize("which", ["DriveStraight", "SetParam"])
def test_a_huge_integer_is_refused_with_value_error(which: str) -> None:
    with pytest.raises(ValueError, match=r"distance_m|value"):
        if which == "DriveStraight":
            cmd.DriveStraight(distance_m=10**400)
        else:
            cmd.SetParam(param="sungaze.timer_s", value=10**400)
