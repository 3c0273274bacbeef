"""``drag_wheel`` on the four drives (issue 22 item 3; Spirit's right front wheel from sol
125, Cheng, Maimone and Matthies 2005 sec. 4.2): every wheel name parses, in text and
JSON, and anything else is an error naming the argument."""

from __future__ import annotations

import pytest

from estimation.geometry import WHEEL_KEYS
from sequences import commands as cmd
from sequences.language import parse, parse_any

DRIVES = {
    "DRIVE_STRAIGHT": "distance_m=2",
    "DRIVE_ARC": "radius_m=3 angle_deg=10",
    "TURN_IN_PLACE": "angle_deg=30",
    "DRIVE_TO": "x_m=3 y_m=1",
}


@pytest.mark.parametrize("name", DRIVES)
@pytest.mark.parametrize("wheel", WHEEL_KEYS)
def test_every_wheel_parses_on_every_drive(name: str, wheel: str) -> None:
    (step,) = parse(f"{name} {DRIVES[name]} drag_wheel={wheel} vo=on\n").steps
    assert step.command.drag_wheel == wheel  # type: ignore[attr-defined]
    assert f"drag_wheel={wheel}" in step.command.describe()


def test_drag_wheel_is_optional_and_parses_from_json() -> None:
    assert cmd.DriveStraight(2.0).drag_wheel is None
    (step,) = parse(
        [{"command": "DRIVE_ARC", "args": {"radius_m": -2.0, "angle_deg": 20, "drag_wheel": "lm"}}]
    ).steps
    assert step.command == cmd.DriveArc(-2.0, 20, drag_wheel="lm")


@pytest.mark.parametrize("bad", ["RF", "xx", "r f", 3, True, ""])
def test_a_bad_wheel_is_an_error_naming_drag_wheel(bad: object) -> None:
    with pytest.raises(ValueError, match=r"^drag_wheel: must be one of lf, lm, lr, rf, rm, rr"):
        cmd.TurnInPlace(angle_deg=10.0, drag_wheel=bad)  # type: ignore[arg-type]
    text = f'"{bad}"' if isinstance(bad, str) else str(bad).lower()
    (found,) = parse_any(f"DRIVE_STRAIGHT distance_m=1 drag_wheel={text}\n").diagnostics
    assert found.code == "bad-value" and found.message.startswith("drag_wheel: must be one of")


def test_drag_wheel_is_published_with_its_choices() -> None:
    (arg,) = (a for a in cmd.DriveTo.argument_table() if a.name == "drag_wheel")
    assert not arg.required and arg.default is None
    assert all(k in arg.spec.note for k in WHEEL_KEYS)
