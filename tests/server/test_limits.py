"""The limits file and its validation (server.limits): the defaults load and say why; every
kind of bad file or level is refused with a message naming the channel and the problem;
levels judge values as their kind and direction say."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import pytest

from server.channels import is_truth
from server.limits import DEFAULTS_FILE, LimitsError, check_levels, load_defaults, parse_defaults

CHANNELS = {
    "aqf", "imu_integration_s", "nate_mode", "tilt_accel_deg", "vo_failures_in_row",
    "hga_margin_predicted_deg", "hga_margin_deg", "hga_error_deg", "position_error_m",
}  # fmt: skip
TRUTH = {"hga_margin_deg", "hga_error_deg", "position_error_m"}


def _document() -> dict[str, Any]:
    document: dict[str, Any] = json.loads(DEFAULTS_FILE.read_text())
    return document


def test_the_defaults_load_with_their_sources_and_truth_flags() -> None:
    limits = load_defaults()
    assert set(limits) == CHANNELS
    assert {n for n, c in limits.items() if c.truth} == TRUTH
    assert all(c.why and (c.units or c.kind != "numeric" or c.channel == "vo_failures_in_row")
               for c in limits.values())  # fmt: skip
    assert "Ali et al. 2005 sec. 4" in limits["imu_integration_s"].why
    imu = limits["imu_integration_s"]
    assert [imu.level_of(v) for v in (7999.0, 8000.1, 10000.1, math.nan, None)] == [
        None, "warning", "critical", None, None,
    ]  # fmt: skip
    margin = limits["hga_margin_predicted_deg"]
    assert [margin.level_of(v) for v in (0.5, 0.09, -0.01)] == [None, "warning", "critical"]
    aqf = limits["aqf"]
    assert [aqf.level_of(v) for v in ("Fine", "Coarse", "TiltOnly", "Unknown", "Bogus")] == [
        None, None, "warning", "critical", None,
    ]  # fmt: skip
    assert limits["nate_mode"].level_of("Gyrocompass") is None
    assert limits["hga_error_deg"].level_of(30.0) is None  # no levels by default


@pytest.mark.parametrize(
    ("change", "problem"),
    [
        ({"channels": []}, '"channels" (an object)'),
        ({"extra": 1}, "unknown top-level key(s) extra"),
        ({"channels": {"x": {"kind": "fuzzy"}}}, "x.kind"),
        ({"channels.aqf.warning": "Splendid"}, "aqf.warning: must be one of"),
        ({"channels.aqf.critical": "Fine"}, "aqf: critical (Fine) must be at or below"),
        ({"channels.imu_integration_s.critical": 5000.0}, "must be at or above warning"),
        ({"channels.imu_integration_s.warning": "8000"}, "must be a finite number or null"),
        ({"channels.imu_integration_s.warning": True}, "must be a finite number or null"),
        ({"channels.imu_integration_s.hysteresis": -1}, "hysteresis must be a finite number >= 0"),
        ({"channels.imu_integration_s.direction": "up"}, "direction: low or high"),
        ({"channels.imu_integration_s.truth": False}, "unknown key(s) truth"),  # channels'
        ({"channels.aqf.needs": "luck"}, "aqf.needs: one of"),
        ({"channels.aqf.shelved_while_acquiring": 1}, "shelved_while_acquiring: a bool"),
        ({"channels.imu_integration_s.why": None}, "why: required"),
        ({"channels.imu_integration_s.colour": "red"}, "unknown key(s) colour"),
        ({"channels.nate_mode.warning": ["Flying"]}, "unknown state(s) 'Flying'"),
        (
            {"channels.nate_mode.critical": ["Idle"], "channels.nate_mode.warning": ["Idle"]},
            "Idle both warning and critical",
        ),
        ({"channels.aqf.values": ["Fine", "Fine"]}, "aqf.values: a list of distinct names"),
    ],
)
def test_a_bad_file_is_refused_naming_the_channel_and_the_problem(
    change: dict[str, Any], problem: str, tmp_path: Path
) -> None:
    document = _document()
    for dotted, value in change.items():
        *path, key = dotted.split(".")
        target = document
        for part in path:
            target = target[part]
        target[key] = value
    with pytest.raises(LimitsError) as refused:
        parse_defaults(document)
    assert problem in str(refused.value)
    bad = tmp_path / "limits.json"
    bad.write_text(json.dumps(document))
    with pytest.raises(LimitsError, match=r"limits\.json: "):
        load_defaults(bad)


def test_a_file_that_is_not_json_is_named() -> None:
    with pytest.raises(LimitsError, match=r"nowhere\.json"):
        load_defaults(Path("/nonexistent/nowhere.json"))


def test_check_levels_validates_an_operators_change() -> None:
    limits = load_defaults()
    margin = limits["hga_margin_deg"]
    new = check_levels(margin, {"warning": 1, "critical": None, "hysteresis": 0.2})
    assert (new.warning, new.critical, new.hysteresis) == (1.0, None, 0.2)
    assert new.level_of(0.9) == "warning" and new.level_of(-5.0) == "warning"
    assert not new.inside(1.1) and new.inside(1.2)  # back inside by the hysteresis
    for levels, problem in (
        ({"warning": 1.0}, "critical required"),
        ({"warning": math.inf, "critical": 0.0}, "finite number"),
        ({"warning": 1.0, "critical": 0.0, "colour": 1}, "unknown field(s) colour"),
    ):
        with pytest.raises(LimitsError, match=re.escape(problem)):
            check_levels(margin, levels)
    with pytest.raises(LimitsError, match="numeric channels only"):
        check_levels(limits["aqf"], {"warning": "Coarse", "critical": None, "hysteresis": 1.0})


def test_the_truth_flag_is_the_channels_rule_and_the_default_alarms_judge_rover_channels() -> None:
    """Issue 21: every limit carries ``truth`` from ``server.channels`` (one rule, not a
    second list in the file), and no default level is on a truth channel: the defaults
    judge what the rover itself reports (the predicted HGA margin, not the true one)."""
    limits = load_defaults()
    assert all(c.truth == is_truth(name) for name, c in limits.items())
    alarmed = {n for n, c in limits.items() if c.kind != "state" and
               (c.warning is not None or c.critical is not None)}  # fmt: skip
    assert alarmed == {"aqf", "imu_integration_s", "tilt_accel_deg", "vo_failures_in_row",
                       "hga_margin_predicted_deg"}  # fmt: skip
    assert not any(limits[n].truth for n in alarmed)
    assert all(limits[n].as_json()["truth"] for n in TRUTH)
    # the predicted margin means nothing without a heading; the true HGA figures nothing
    # with Earth below the horizon
    assert limits["hga_margin_predicted_deg"].needs == "heading"
    assert limits["hga_margin_deg"].needs == limits["hga_error_deg"].needs == "earth_up"
    assert {n for n, c in limits.items() if c.shelved_while_acquiring} == {
        "aqf", "hga_margin_predicted_deg", "hga_margin_deg", "hga_error_deg"}  # fmt: skip
