"""``roverops ephem`` report: exact keys, consistency with the parts, and every bad input."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

from cli.ephem_report import ephem_report, parse_utc
from sim.errors import InputError

EXAMPLE = ("2004-01-03T13:46:31", -14.64, 184.702)  # GISS Mars24 worked example 2
SECTION_KEYS = {
    "sun_elev_deg",
    "sun_azimuth_deg",
    "earth_elev_deg",
    "earth_azimuth_deg",
    "sun_ll",
    "earth_ll",
}


def _angle_deg(a: list[float], b: list[float]) -> float:
    return math.degrees(math.acos(min(1.0, float(np.dot(a, b)))))


def test_keys_are_exactly_the_contract() -> None:
    without = ephem_report(*EXAMPLE, None)
    with_sol = ephem_report(*EXAMPLE, "spirit")
    top = {"msd", "mst_h", "lmst_h", "ltst_h", "ls_deg", "mars24", "truth", "ivp"}
    assert set(without) == top
    assert set(with_sol) == top | {"sol"}
    assert set(with_sol["mars24"]) == {"sun_elev_deg", "sun_azimuth_deg"}
    assert set(with_sol["truth"]) == SECTION_KEYS
    assert set(with_sol["ivp"]) == SECTION_KEYS
    # Plain JSON types throughout.
    assert json.loads(json.dumps(with_sol)) == with_sol


def test_worked_example_values() -> None:
    r = ephem_report(*EXAMPLE, "spirit")
    assert r["sol"] == 1  # LMST 00:51 at the site: Spirit's landing sol has begun
    assert r["lmst_h"] == pytest.approx(0.85190, abs=1e-4)
    assert r["ltst_h"] == pytest.approx(0.00025, abs=1e-4)
    assert r["ls_deg"] == pytest.approx(327.32416, abs=1e-3)
    assert r["mars24"]["sun_elev_deg"] == pytest.approx(90.0 - 151.93895, abs=1e-3)
    # Local true midnight: the Sun is due North-South below the horizon in all three.
    for section in ("truth", "ivp"):
        assert r[section]["sun_elev_deg"] == pytest.approx(-62.0, abs=0.3)
        assert abs(r[section]["sun_azimuth_deg"] - 180.0) < 0.1


def test_sections_are_consistent() -> None:
    r: dict[str, Any] = ephem_report("2012-08-06T05:17:57Z", -4.59, 222.55, None)
    for section in ("truth", "ivp"):
        s = r[section]
        for body in ("sun", "earth"):
            v = s[f"{body}_ll"]
            assert len(v) == 3
            assert float(np.linalg.norm(v)) == pytest.approx(1.0, abs=1e-12)
            assert s[f"{body}_elev_deg"] == pytest.approx(math.degrees(math.asin(-v[2])))
            az = math.degrees(math.atan2(v[1], v[0])) % 360.0
            assert s[f"{body}_azimuth_deg"] == pytest.approx(az)
    assert _angle_deg(r["truth"]["sun_ll"], r["ivp"]["sun_ll"]) < 0.05
    assert _angle_deg(r["truth"]["earth_ll"], r["ivp"]["earth_ll"]) < 0.1
    assert abs(r["mars24"]["sun_elev_deg"] - r["truth"]["sun_elev_deg"]) < 0.35


@pytest.mark.parametrize(
    "utc", ["2004-01-03T13:46:31Z", "2004-01-03T13:46:31+00:00", " 2004-01-03T13:46:31 "]
)
def test_accepted_time_forms_agree(utc: str) -> None:
    assert ephem_report(utc, *EXAMPLE[1:], None) == ephem_report(*EXAMPLE, None)


def test_fractional_seconds_and_minutes_only() -> None:
    assert parse_utc("2004-01-03T13:46:31.500").microsecond == 500000
    assert parse_utc("2004-01-03T13:46").second == 0


@pytest.mark.parametrize(
    "utc",
    [
        "yesterday",
        "",
        "2004-01-03",  # no time of day
        "2004-01-03 13:46:31",  # space instead of T
        "2004-13-03T13:46:31",  # month 13
        "2004-02-30T00:00:00",  # no such day
        "2004-01-03T25:00:00",
        "2004-01-03T13:46:31+02:00",  # not UTC
        "2004-01-03T13:46:31-08:00",
        "1969-07-20T20:17:00",  # before 1972 (no leap-second UTC)
        "2060-01-01T00:00:00",  # after DE421
    ],
)
def test_bad_utc(utc: str) -> None:
    with pytest.raises(InputError) as err:
        ephem_report(utc, 0.0, 0.0, None)
    assert err.value.parameter == "utc"


@pytest.mark.parametrize("lat", [90.01, -91.0, float("nan"), float("inf"), "10", True])
def test_bad_latitude(lat: Any) -> None:
    with pytest.raises(InputError) as err:
        ephem_report(EXAMPLE[0], lat, 0.0, None)
    assert err.value.parameter == "lat_deg"


@pytest.mark.parametrize("lon", [-0.001, 360.0, 400.0, float("nan"), None])
def test_bad_longitude(lon: Any) -> None:
    with pytest.raises(InputError) as err:
        ephem_report(EXAMPLE[0], 0.0, lon, None)
    assert err.value.parameter == "lon_west_deg"


@pytest.mark.parametrize("mission", ["curiosity", "", 3])
def test_bad_mission(mission: Any) -> None:
    with pytest.raises(InputError) as err:
        ephem_report(EXAMPLE[0], 0.0, 0.0, mission)
    assert err.value.parameter == "mission"


def test_edges_of_the_ranges_are_accepted() -> None:
    for lat, lon in [(90.0, 0.0), (-90.0, 359.999)]:
        r = ephem_report("2030-06-01T00:00:00Z", lat, lon, "opportunity")
        assert r["sol"] > 9000
