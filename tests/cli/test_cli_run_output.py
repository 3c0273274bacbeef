"""``roverops run``'s human output reads as text (issue 21): every figure with its unit, no
Python repr (no ``[...]``, no dict, no ``None``/``True``, no ``np.float64(...)``), and the
same figures as the scenario's summary (``--json``)."""

import re
from typing import Any

import pytest

from cli.main import main
from cli.run_report import print_run
from sim.scenarios.headless import run_scenario

NUMBER = r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?"
UNIT = r"(?: m| mm| s| h|°/h|°| %)"
# Lines whose numbers are not figures with a unit: counts, dates, names, and the commands'
# own text (the sequence language's form, "DRIVE_STRAIGHT distance_m=10.0", and its events).
UNITLESS = (
    "scenario:",
    "description:",
    "seed:",
    "sol:",
    "cycles_simulated:",
    "unsettled_poses:",
    "start_utc:",
    "end_utc:",
)
REPRS = ("[", "]", "{", "}", "np.", "None", "True", "False", "'")


@pytest.fixture(scope="module")
def fine_drive() -> dict[str, Any]:
    estimators = ("sapp", "kinematic_ekf", "radio_ekf")
    return run_scenario("fine_drive_hga", 1, distance_m=10.0, estimators=estimators)


def _printed(result: dict[str, Any], capsys: pytest.CaptureFixture[str]) -> str:
    print_run(result, False)
    return capsys.readouterr().out


def _assert_text(out: str) -> None:
    assert [token for token in REPRS if token in out] == [], out
    in_commands = False
    for line in out.splitlines():
        if not line.startswith(" "):
            in_commands = line.startswith("commands:")
        if in_commands or line.lstrip().startswith(UNITLESS):
            continue
        value = line.split(":", 1)[1]
        bare = re.findall(rf"{NUMBER}(?!\d|\.|e|{UNIT})", value)
        assert bare == [], f"a number without its unit: {line!r}"


def _line(out: str, key: str) -> str:
    """The summary's top-level line of ``key``."""
    found = [line for line in out.splitlines() if line.startswith(f"{key}:")]
    assert len(found) == 1, (key, out)
    return found[0]


def test_run_rest_prints_text_with_units(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--scenario", "rest_1h", "--seed", "1"]) == 0
    out = capsys.readouterr().out
    _assert_text(out)
    assert _line(out, "command") == "command: rest 3600 s"
    assert re.fullmatch(
        rf"final_p_s: x {NUMBER} m, y {NUMBER} m, z {NUMBER} m", _line(out, "final_p_s")
    )
    axes = rf"x {NUMBER}°/h, y {NUMBER}°/h, z {NUMBER}°/h"
    assert re.fullmatch(f"gyro_rate_b_deg_per_h: {axes}", _line(out, "gyro_rate_b_deg_per_h"))


def test_run_with_the_flight_software_prints_text_with_units(
    fine_drive: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    out = _printed(fine_drive, capsys)
    _assert_text(out)
    # one line per command, its status and duration, its events below it
    assert "  GET_FINE_ATTITUDE: completed in 500.25 s" in out
    assert "    nadir (info): Nadir Update succeeded" in out
    # a figure an estimator does not have reads as such, not as None
    radio = out.split("  radio_ekf:")[1]
    assert "attitude_error_deg: not estimated" in radio.splitlines()[3]
    assert _line(out, "earth_above_horizon") == "earth_above_horizon: yes"


def test_run_text_has_the_summary_figures(
    fine_drive: dict[str, Any], capsys: pytest.CaptureFixture[str]
) -> None:
    out = _printed(fine_drive, capsys)
    for key in ("distance_truth_m", "position_error_m", "hga_margin_deg", "wall_s"):
        figure = float(re.findall(NUMBER, _line(out, key))[0])
        assert figure == pytest.approx(fine_drive[key], rel=1e-5)
    truth = [float(v) for v in re.findall(NUMBER, _line(out, "p_s_true"))]
    assert truth == pytest.approx(fine_drive["p_s_true"], rel=1e-5, abs=1e-9)
    kinematic = fine_drive["estimators"]["kinematic_ekf"]["position_error_m"]
    line = out.split("  kinematic_ekf:")[1].splitlines()[1]
    assert float(re.findall(NUMBER, line)[0]) == pytest.approx(kinematic, rel=1e-5)
