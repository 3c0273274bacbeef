"""The sequence language (``sequences.language``, ``sequences.validate``) and ``roverops validate``.

Fixed inputs throughout: the parser on every time-tag form and value type, round trips
through text and JSON, many errors reported together at the right lines and columns, the
warnings of the predicting walk with a fake rover clock (plain lambdas), the examples and the
documentation (``roverops validate``: tests/cli/test_cli_validate.py).
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from pathlib import Path
from typing import Any

import pytest

from sequences import commands as cmd
from sequences.language import (
    NO_TAG,
    Sequence,
    SequenceError,
    TimeTag,
    format_value,
    from_json,
    parse,
    parse_value,
    to_json,
    to_text,
)
from sequences.validate import (
    CODES,
    ValidationContext,
    ValidationResult,
    estimate_duration_s,
    validate,
)

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "sequences" / "examples"
DOC = ROOT / "docs" / "sequences.md"

# ---- a fake rover clock: sol 0 starts at t_s = 0, the LMST day is one mean sol ---------
SOL_S = 88775.244


def _lmst_h(t_s: float) -> float:
    return (t_s % SOL_S) / SOL_S * 24.0


def _context(**changes: Any) -> ValidationContext:
    """Sol 42 at 08:00 LMST; Earth up from 09:00 to 15:00 LMST."""
    values: dict[str, Any] = {
        "start_t_s": (42 + 8.0 / 24.0) * SOL_S,
        "lmst_h": _lmst_h,
        "sol": lambda t: int(t // SOL_S),
        "t_s_for": lambda sol, h: (sol + h / 24.0) * SOL_S,
        "earth_elevation_deg": lambda t: 20.0 if 9.0 <= _lmst_h(t) < 15.0 else -5.0,
        "aqf": "Fine",
        "imu_integration_s": 0.0,
    }
    values.update(changes)
    return ValidationContext(**values)


def _where(result: ValidationResult, severity: str = "error") -> list[tuple[int, int, str]]:
    found = result.errors if severity == "error" else result.warnings
    return [(d.line, d.column, d.code) for d in found]


def _codes(result: ValidationResult) -> list[tuple[int, str]]:
    return [(d.line, d.code) for d in result.warnings]


# ---- the parser -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("tag", "expected"),
    [
        ("@ 10:00 LMST", TimeTag("lmst", lmst_s=36000)),
        ("@ 9:05:30 LMST", TimeTag("lmst", lmst_s=9 * 3600 + 5 * 60 + 30)),
        ("@23:59:59 LMST", TimeTag("lmst", lmst_s=86399)),
        ("@ sol 42 10:00 LMST", TimeTag("sol_lmst", lmst_s=36000, sol=42)),
        ("@ sol 0 00:00:01 LMST", TimeTag("sol_lmst", lmst_s=1, sol=0)),
        ("@ +00:10:00", TimeTag("relative", after_s=600.0)),
        ("@ +48:00:00", TimeTag("relative", after_s=172800.0)),
        ("@ +90s", TimeTag("relative", after_s=90.0)),
        ("@ +2.5s", TimeTag("relative", after_s=2.5)),
        ("", NO_TAG),
    ],
)
def test_every_time_tag_form(tag: str, expected: TimeTag) -> None:
    seq = parse(f"{tag} PLANT_SITE\n")
    assert seq.steps[0].time_tag == expected
    assert isinstance(seq.steps[0].command, cmd.PlantSite)


def test_time_tag_hours() -> None:
    assert TimeTag("lmst", lmst_s=37800).lmst_h == 10.5
    assert TimeTag("lmst", lmst_s=37800).clock() == "10:30"
    assert TimeTag("sol_lmst", lmst_s=37805, sol=1).clock() == "10:30:05"
    assert NO_TAG.lmst_h is None and not NO_TAG.absolute


@pytest.mark.parametrize(
    ("text", "value"),
    [
        ("4", 4),
        ("-3", -3),
        ("+7", 7),
        ("4.0", 4.0),
        ("-0.5", -0.5),
        (".5", 0.5),
        ("1e3", 1000.0),
        ("2.5E-1", 0.25),
        ("on", True),
        ("ON", True),
        ("true", True),
        ("off", False),
        ("False", False),
        ("sungaze.timer_s", "sungaze.timer_s"),
        ("min-elev_2", "min-elev_2"),
        ('"a b # c"', "a b # c"),
        ('"say \\"hi\\" \\\\ there"', 'say "hi" \\ there'),
        ('""', ""),
    ],
)
def test_every_value_type(text: str, value: object) -> None:
    parsed = parse_value(text)
    assert parsed == value and type(parsed) is type(value)


@pytest.mark.parametrize("text", ["", "4.0m", "1/2", "3deg", '"open', '"ends with \\"', "@x"])
def test_values_that_are_not_values(text: str) -> None:
    with pytest.raises(ValueError):
        parse_value(text)


def test_values_reach_the_commands_with_their_types() -> None:
    seq = parse(
        "SUNGAZE use_gravity=on\n"
        "SUNGAZE use_gravity=false\n"
        "SET_PARAM param=sungaze.timer_s value=300\n"
        'SET_PARAM param="sungaze.early_stop" value=off\n'
        "SET_PARAM param=min_sun_elevation_rad value=-5e-2\n"
        "DRIVE_ARC radius_m=-3.5 angle_deg=20\n"
    )
    commands = [s.command for s in seq.steps]
    assert commands == [
        cmd.Sungaze(use_gravity=True),
        cmd.Sungaze(use_gravity=False),
        cmd.SetParam(param="sungaze.timer_s", value=300),
        cmd.SetParam(param="sungaze.early_stop", value=False),
        cmd.SetParam(param="min_sun_elevation_rad", value=-0.05),
        cmd.DriveArc(radius_m=-3.5, angle_deg=20),
    ]
    assert commands[2].value is not True and isinstance(commands[2].value, int)  # type: ignore[attr-defined]


def test_comments_blank_lines_name_and_positions() -> None:
    text = (
        "# a header\n"
        "\n"
        "   # an indented comment\n"
        "SEQUENCE my-seq_1   # the name\n"
        "\t@ 10:00 LMST   SUNCHECK_SUNGAZE # Fine first\n"
        "\n"
        '  SET_PARAM param="a#b" value=1  # the # in the string is kept\n'
        "DRIVE_STRAIGHT distance_m=4.0#no space before the comment\n"
    )
    seq = parse(text)
    assert seq.name == "my-seq_1"
    assert [(s.line, s.column, s.tag_column) for s in seq.steps] == [
        (5, 17, 2),
        (7, 3, 0),
        (8, 1, 0),
    ]
    assert seq.steps[1].command == cmd.SetParam(param="a#b", value=1)
    assert seq.steps[2].command == cmd.DriveStraight(distance_m=4.0)
    assert parse("PLANT_SITE\r\nSUNFIND\r\n").steps[1].line == 2
    assert parse("PLANT_SITE").name is None


def test_the_text_and_json_forms_give_the_same_sequence() -> None:
    text = (
        "SEQUENCE sol43_articulate_hga\n"
        "@ sol 43 10:00 LMST SUNCHECK_SUNGAZE\n"
        "@ +60s ARTICULATE_START\n"
        "WAIT duration_s=600\n"
        "ARTICULATE_STOP\n"
        "SET_PARAM param=sungaze.use_gravity value=true\n"
        'SET_PARAM param="sungaze.timer_s" value=300\n'
        "SUNCHECK_SUNGAZE\n"
        "@ 12:30 LMST HGA_PASS duration_min=15\n"
    )
    from_file = parse((EXAMPLES / "sol43_articulate_hga.json").read_text())
    assert parse(text) == from_file
    assert from_file.steps[0].where == "steps[0]" and from_file.steps[0].line == 0
    as_list = json.loads(to_json(from_file))["steps"]
    assert from_json(as_list) == Sequence(None, from_file.steps)  # a bare list of steps


@pytest.mark.parametrize("path", sorted(EXAMPLES.iterdir()), ids=lambda p: p.name)
def test_round_trip_through_text_and_json(path: Path) -> None:
    seq = parse(path.read_text())
    assert seq.steps
    assert parse(to_text(seq)) == seq
    assert from_json(to_json(seq)) == seq
    assert from_json(json.loads(to_json(seq, indent=None))) == seq
    assert parse(to_json(seq)) == seq  # parse tells JSON from text


def test_round_trip_of_awkward_values() -> None:
    seq = Sequence(
        "odd",
        tuple(
            parse(line).steps[0]
            for line in (
                'SET_PARAM param="has space" value=1e-300',
                'SET_PARAM param="on" value=true',
                'SET_PARAM param="q\\"uote\\\\" value=-0.0',
                "@ +0.125s WAIT duration_s=0.001",
                "@ sol 7 00:00:59 LMST DRIVE_STRAIGHT distance_m=100",
            )
        ),
    )
    again = parse(to_text(seq))
    assert again == seq and from_json(to_json(seq)) == seq
    assert again.steps[1].command == cmd.SetParam(param="on", value=True)
    assert format_value("on") == '"on"' and format_value(True) == "true"
    assert "@ +0.125s WAIT" in to_text(seq)


# ---- errors -----------------------------------------------------------------------------

MANY_ERRORS = """\
# header comment
SEQUENCE bad_one
@ 10:00 LMST SUNCHECK_SUNGAZE
DRIVE_STRAIGHT distance_m=0
DRIVE_ARC radius_m=3.5
drive_straight distance_m=4
WAIT duration_s=5 duration_s=6
@ 25:00 LMST WAIT duration_s=5
@ 09:00 LMST HGA_PASS
SEQUENCE late
TURN_IN_PLACE angle_deg=4.0deg
@ +10s
PLANT_SITE now
ARTICULATE_STOP
SUNFIND tolerance_deg=1
@ 10:00 WAIT duration_s=1 nonsense
"""


def test_many_errors_are_reported_together_at_their_lines_and_columns() -> None:
    result = validate(MANY_ERRORS)
    assert not result.ok and result.sequence is None
    assert _where(result) == [
        (4, 27, "bad-value"),
        (5, 1, "missing-argument"),
        (6, 1, "unknown-command"),
        (7, 19, "duplicate-argument"),
        (8, 1, "bad-time-tag"),
        (9, 1, "time-backwards"),
        (10, 1, "sequence-not-first"),
        (11, 25, "bad-value"),
        (12, 1, "missing-command"),
        (13, 12, "syntax"),
        (14, 1, "not-articulating"),
        (15, 9, "unknown-argument"),
        (16, 1, "bad-time-tag"),
        (16, 27, "syntax"),
    ]
    messages = {d.line: d.message for d in result.errors}
    assert messages[4].startswith("distance_m: must be in (0, 100] m")
    assert "angle_deg" in messages[5]
    assert "upper case (DRIVE_STRAIGHT)" in messages[6]
    assert "line 3" in messages[9] and "next sol" in messages[9]
    assert "units go in the argument name" in messages[11]
    assert result.warnings == []
    with pytest.raises(SequenceError) as info:
        parse(MANY_ERRORS)
    assert len(info.value.diagnostics) == len(result.errors) - 2  # the cross-line checks
    assert "(and 11 more)" in str(info.value)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("", [(1, 1, "empty")]),
        ("# only a comment\n\n", [(1, 1, "empty")]),
        ("SEQUENCE has space\nPLANT_SITE", [(1, 10, "bad-name")]),
        ("SEQUENCE " + "x" * 65 + "\nPLANT_SITE", [(1, 10, "bad-name")]),
        ("PLANT_SITE\nSEQUENCE late", [(2, 1, "sequence-not-first")]),
        ("@ 10:00 LMST SEQUENCE x", [(1, 14, "unknown-command"), (1, 23, "syntax")]),
        ("@ 12:60 LMST PLANT_SITE", [(1, 1, "bad-time-tag")]),
        ("@ sol 100001 10:00 LMST PLANT_SITE", [(1, 1, "bad-time-tag")]),
        ("@ +00:61:00 PLANT_SITE", [(1, 1, "bad-time-tag")]),
        ("@ +200000s PLANT_SITE", [(1, 1, "bad-time-tag")]),
        ("@ 10:00 lmst PLANT_SITE", [(1, 1, "bad-time-tag")]),
        ("  @ 10:00 LMST", [(1, 3, "missing-command")]),
        ("PLANT_SITE @ 10:00 LMST", [(1, 12, "syntax"), (1, 14, "syntax"), (1, 20, "syntax")]),
        ("WAIT duration_s=", [(1, 17, "bad-value")]),
        ("SUNGAZE use_gravity=1", [(1, 21, "bad-value")]),
        ("DRIVE_STRAIGHT distance_m=on", [(1, 27, "bad-value")]),
        ("DRIVE_ARC radius_m=50 angle_deg=120", [(1, 33, "bad-value")]),
        ("HGA_PASS duration_min=121 x=1", [(1, 27, "unknown-argument")]),
        ("@ 13:00 LMST WAIT duration_s=1\n@ 10:00 LMST PLANT_SITE", [(2, 1, "time-backwards")]),
        (
            "@ sol 5 13:00 LMST PLANT_SITE\n@ sol 5 12:59:59 LMST PLANT_SITE",
            [(2, 1, "time-backwards")],
        ),
        (
            "@ 13:00 LMST WAIT duration_s=1\n@ 13:00 LMST PLANT_SITE\n@ sol 1 01:00 LMST SUNFIND",
            [],
        ),
        (
            "ARTICULATE_START\nPLANT_SITE\nDRIVE_STRAIGHT distance_m=1\nARTICULATE_START\n"
            "WAIT duration_s=5\nHGA_PASS\nARTICULATE_STOP\nARTICULATE_STOP\nPLANT_SITE",
            [
                (2, 1, "refused-in-articulate"),
                (3, 1, "refused-in-articulate"),
                (4, 1, "refused-in-articulate"),
                (8, 1, "not-articulating"),
            ],
        ),
    ],
)
def test_each_kind_of_error(text: str, expected: list[tuple[int, int, str]]) -> None:
    result = validate(text)
    assert _where(result) == expected
    assert result.ok == (not expected)
    assert all(CODES[d.code] == "error" for d in result.errors)


def test_json_errors_carry_their_location() -> None:
    source = json.dumps(
        {
            "name": "x y",
            "extra": 1,
            "steps": [
                {"command": "DRIVE_STRAIGHT", "args": {"distance_m": -4}},
                {"command": "WAIT", "time": {"lmst": "25:00"}},
                {"command": "NOPE"},
                {"command": "WAIT", "args": {"duration_s": 5, "x": 1}, "foo": 1},
                3,
                {"command": "HGA_PASS", "time": {"sol": True, "lmst": "10:00"}},
                {"command": "WAIT", "args": {"duration_s": 5}, "time": {"sol": 4, "lmst": "10:00"}},
                {"command": "WAIT", "args": {"duration_s": 5}, "time": {"sol": 3, "lmst": "10:00"}},
                {"command": "PLANT_SITE", "time": {"after_s": -1}},
                {"command": "PLANT_SITE", "time": {"at": "10:00"}},
                {"command": "SUNGAZE", "args": {"use_gravity": "yes"}},
                {"command": "ARTICULATE_STOP"},
            ],
        }
    )
    result = validate(source)
    assert {(d.line, d.column) for d in result.errors} == {(0, 0)}
    found = [(d.code, d.message.split(":")[0]) for d in result.errors]
    assert found == [
        ("bad-structure", "extra"),
        ("bad-name", "name"),
        ("bad-value", "steps[0].args.distance_m"),
        ("bad-time-tag", "steps[1].time.lmst"),
        ("missing-argument", "steps[1].args"),
        ("unknown-command", "steps[2].command"),
        ("bad-structure", "steps[3].foo"),
        ("unknown-argument", "steps[3].args.x"),
        ("bad-structure", "steps[4]"),
        ("bad-time-tag", "steps[5].time.sol"),
        ("bad-time-tag", "steps[8].time.after_s"),
        ("bad-time-tag", "steps[9].time"),
        ("bad-value", "steps[10].args.use_gravity"),
        ("time-backwards", "steps[7].time"),
        ("not-articulating", "steps[11]"),
    ]


def test_json_syntax_and_shape_errors() -> None:
    broken = validate('{"steps": [\n  {"command": "PLANT_SITE",}\n]}')
    assert _where(broken) == [(2, 28, "bad-json")]
    dup = '{"steps": [{"command": "WAIT", "args": {"duration_s": 1, "duration_s": 2}}]}'
    assert [d.message for d in validate(dup).errors] == [
        "steps[0].args.duration_s: given more than once"
    ]
    assert [d.code for d in validate("[]").errors] == ["empty"]
    assert [d.code for d in validate('{"steps": {}}').errors] == ["bad-structure"]
    assert [d.code for d in validate({"steps": [{"command": 5}]}).errors] == ["bad-structure"]
    assert [d.code for d in validate({"steps": [{"args": {}}]}).errors] == ["bad-structure"]
    null_args = validate({"steps": [{"command": "NADIR_UPDATE", "args": {"window_s": None}}]})
    assert null_args.ok and null_args.sequence is not None
    assert null_args.sequence.steps[0].command == cmd.NadirUpdate()


def test_a_valid_sequence_is_returned() -> None:
    result = validate("SEQUENCE ok\nSUNCHECK_SUNGAZE\nDRIVE_STRAIGHT distance_m=2")
    assert result.ok and result.errors == [] and result.warnings == []
    assert result.sequence is not None and result.sequence.name == "ok"
    assert result.as_dict() == {"ok": True, "errors": [], "warnings": []}


# ---- warnings (a fake rover: sol 42 08:00 LMST, Earth up 09:00-15:00) -------------------


def test_no_prediction_warnings_without_a_context() -> None:
    text = "DRIVE_STRAIGHT distance_m=100\nDRIVE_STRAIGHT distance_m=100\n@ 03:00 LMST HGA_PASS"
    assert validate(text).warnings == []
    assert _codes(validate(text, _context(aqf="Unknown"))) == [
        (1, "drive-not-fine"),
        (2, "drive-not-fine"),
        (3, "tag-next-sol"),  # the drives end after 03:00 LMST
        (3, "earth-below-horizon"),
        (3, "hga-not-fine"),
    ]


def test_drive_warnings_follow_the_predicted_aqf() -> None:
    assert validate("DRIVE_STRAIGHT distance_m=5", _context(aqf="Fine")).warnings == []
    for aqf in ("Unknown", "TiltOnly", "Coarse"):
        result = validate("TURN_IN_PLACE angle_deg=10", _context(aqf=aqf))
        assert _where(result, "warning") == [(1, 1, "drive-not-fine")]
        assert aqf in result.warnings[0].message
    # acquisitions change the prediction: Coarse is not enough, Fine is
    text = (
        "GET_COARSE_ATTITUDE\nDRIVE_ARC radius_m=5 angle_deg=10\n"
        "SUNCHECK_SUNGAZE\nDRIVE_STRAIGHT distance_m=30\n"  # 800 s: still Fine
        "DRIVE_STRAIGHT distance_m=10\n"  # passes 900 s of propagation: drops to Coarse
        "TURN_IN_PLACE angle_deg=-90\n"
        "GYROCOMPASS\nDRIVE_STRAIGHT distance_m=1\n"
        "GET_FINE_ATTITUDE\nSET_PARAM param=fine_to_coarse_s value=5000\n"
        "DRIVE_STRAIGHT distance_m=100\nDRIVE_STRAIGHT distance_m=1\n"
    )
    result = validate(text, _context(aqf="Unknown"))
    assert _codes(result) == [
        (2, "drive-not-fine"),
        (5, "fine-expires"),
        (6, "drive-not-fine"),
        (8, "drive-not-fine"),
    ]
    assert "100 s into this command's 267 s of driving" in result.warnings[1].message


def test_hga_warnings_use_the_predicted_start() -> None:
    text = (
        "@ +00:20:00 HGA_PASS\n"  # 08:19 LMST: Earth down
        "@ 12:00 LMST HGA_PASS duration_min=30\n"  # up throughout
        "@ 14:50 LMST HGA_PASS duration_min=20\n"  # sets at 15:00
    )
    result = validate(text, _context())
    assert _where(result, "warning") == [
        (1, 13, "earth-below-horizon"),
        (3, 14, "earth-below-horizon"),
    ]
    assert "below the horizon at sol 42 08:19 LMST" in result.warnings[0].message
    assert "sets before the pass ends" in result.warnings[1].message
    coarse = validate("@ 12:00 LMST HGA_PASS", _context(aqf="Coarse"))
    assert _where(coarse, "warning") == [(1, 14, "hga-not-fine")]


def test_imu_time_warns_once_until_a_sungaze() -> None:
    text = (
        "WAIT duration_s=500\n"  # Idle: the gyros are not integrated
        "DRIVE_STRAIGHT distance_m=10\n"  # 9900 + 267 s
        "DRIVE_STRAIGHT distance_m=10\n"
        "SUNGAZE\n"
        "DRIVE_STRAIGHT distance_m=100\n"
        "ARTICULATE_START\n"
        "WAIT duration_s=7000\n"  # 2667 + 7000 s
        "HGA_PASS duration_min=10\n"  # Articulate: 600 s more
        "ARTICULATE_STOP\n"
    )
    result = validate(text, _context(aqf="Coarse", imu_integration_s=9900.0))
    imu = [(d.line, d.message) for d in result.warnings if d.code == "imu-time"]
    assert [line for line, _ in imu] == [2, 8]
    assert "10167 s" in imu[0][1] and "10267 s" in imu[1][1]


def test_time_tag_warnings() -> None:
    late = "@ 08:10 LMST WAIT duration_s=3600\n@ 08:30 LMST PLANT_SITE\n"
    result = validate(late, _context())
    assert _where(result, "warning") == [(2, 1, "tag-next-sol")]
    assert "until sol 43" in result.warnings[0].message
    passed = "WAIT duration_s=7200\n@ sol 42 08:30 LMST PLANT_SITE\n"
    assert _where(validate(passed, _context()), "warning") == [(2, 1, "tag-passed")]
    # the first command may wait for tomorrow: no warning
    assert validate("@ 07:00 LMST PLANT_SITE", _context()).warnings == []
    assert validate("@ sol 43 07:00 LMST PLANT_SITE", _context()).warnings == []


def test_articulate_state_and_context() -> None:
    opened = validate("ARTICULATE_START\nWAIT duration_s=5\n")
    assert opened.ok and _where(opened, "warning") == [(1, 1, "articulate-open")]
    busy = _context(articulating=True)
    assert validate("ARTICULATE_STOP\nPLANT_SITE", busy).ok
    assert _where(validate("PLANT_SITE", busy)) == [(1, 1, "refused-in-articulate")]
    assert _where(validate("ARTICULATE_STOP")) == [(1, 1, "not-articulating")]


def test_json_warnings_carry_the_step() -> None:
    drive = {"command": "DRIVE_STRAIGHT", "args": {"distance_m": 1}}
    result = validate({"steps": [drive]}, _context(aqf="Coarse"))
    assert [(d.line, d.code, d.message[:10]) for d in result.warnings] == [
        (0, "drive-not-fine", "steps[0]: ")
    ]


def test_the_context_is_checked() -> None:
    with pytest.raises(ValueError, match=r"^aqf: "):
        _context(aqf="Great")
    with pytest.raises(ValueError, match="finite"):
        _context(imu_integration_s=math.nan)


def test_duration_estimates() -> None:
    assert estimate_duration_s(cmd.DriveStraight(distance_m=3.75)) == pytest.approx(100.0)
    assert estimate_duration_s(cmd.DriveArc(radius_m=-3.0, angle_deg=90.0)) == pytest.approx(
        3.0 * math.pi / 2 / 0.0375
    )
    assert estimate_duration_s(cmd.TurnInPlace(angle_deg=-21.0)) == pytest.approx(10.0)
    assert estimate_duration_s(cmd.NadirUpdate()) == 10.0
    assert estimate_duration_s(cmd.NadirCheck(window_s=30)) == 30.0
    assert estimate_duration_s(cmd.Sunfind()) == 300.0
    assert estimate_duration_s(cmd.Sungaze()) == 600.0
    assert estimate_duration_s(cmd.GetFineAttitude()) == 900.0
    assert estimate_duration_s(cmd.SuncheckSungaze()) == 660.0
    assert estimate_duration_s(cmd.Gyrocompass()) == 1800.0
    assert estimate_duration_s(cmd.Gyrocompass(), gyrocompass_s=60.0) == 60.0
    assert estimate_duration_s(cmd.HgaPass(duration_min=2)) == 120.0
    assert estimate_duration_s(cmd.Wait(duration_s=5)) == 5.0
    assert estimate_duration_s(cmd.PlantSite()) == 0.0


# ---- examples and documentation ---------------------------------------------------------


def test_there_are_the_required_examples() -> None:
    names = {p.name for p in EXAMPLES.iterdir()}
    assert "fine_attitude_then_drive.seq" in names
    assert len([n for n in names if n.endswith(".seq")]) >= 5
    assert any(n.endswith(".json") for n in names)
    first = parse((EXAMPLES / "fine_attitude_then_drive.seq").read_text())
    assert [type(s.command) for s in first.steps] == [cmd.SuncheckSungaze, cmd.DriveStraight]


@pytest.mark.parametrize("path", sorted(EXAMPLES.iterdir()), ids=lambda p: p.name)
def test_every_example_validates(path: Path) -> None:
    source = path.read_text()
    for context in (None, _context(aqf="Coarse")):
        result = validate(source, context)
        assert result.errors == [], [d.format(path.name) for d in result.errors]
        assert result.sequence is not None and result.sequence.name == path.stem


def test_the_documentation_lists_every_command_argument_and_code() -> None:
    doc = DOC.read_text()
    rows = {
        line.split("|")[1].strip().strip("`"): line
        for line in doc.splitlines()
        if line.startswith("| `")
    }
    for name, kind in cmd.COMMANDS.items():
        assert name in rows, f"{name} has no row in docs/sequences.md"
        for argument in (f.name for f in dataclasses.fields(kind)):
            assert f"`{argument}`" in rows[name], f"{name}.{argument} is not documented"
    for code in CODES:
        assert code in rows, f"diagnostic code {code} is not documented"


# ---- size ---------------------------------------------------------------------------------


def test_ten_thousand_lines_validate(capsys: pytest.CaptureFixture[str]) -> None:
    """Speed belongs in ``roverops bench server``; this only shows the figure."""
    block = (
        "@ +00:01:00 SUNCHECK_SUNGAZE\nDRIVE_ARC radius_m=3.5 angle_deg=20\n"
        "DRIVE_STRAIGHT distance_m=4.0  # comment\nTURN_IN_PLACE angle_deg=-45\n"
        'SET_PARAM param="sungaze.timer_s" value=300\nNADIR_CHECK tolerance_deg=1.5 window_s=10\n'
        "PLANT_SITE\nHGA_PASS duration_min=15\nWAIT duration_s=60\n\n"
    )
    source = block * 1000
    assert len(source.splitlines()) == 10_000
    t0 = time.perf_counter()
    result = validate(source, _context())
    elapsed = time.perf_counter() - t0
    with capsys.disabled():
        print(f"\nvalidate 10,000 lines: {elapsed:.3f} s")
    assert result.ok and result.sequence is not None and len(result.sequence.steps) == 9000
