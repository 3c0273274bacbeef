"""``roverops ephem`` report: exact keys, consistency with the parts, and every bad input."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

from cli.ephem_report import ephem_report, minutes_seconds, parse_utc, print_ephem
from sim.errors import InputError
from sim.world.ephemeris import C_KM_S, astrometric_from_mars_j2000_km
from sim.world.marsclock import utc_to_t_s

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
    top = {"msd", "mst_h", "lmst_h", "ltst_h", "ls_deg", "one_way_light_time_s"}
    top |= {"mars24", "truth", "ivp"}
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


def test_the_light_time_is_the_ephemeris_distance_to_earth_over_c() -> None:
    r = ephem_report(*EXAMPLE, None)
    # the distance to where Earth was when its light left: the same equation, solved by the
    # ephemeris for Earth's direction
    t_s = utc_to_t_s(parse_utc(EXAMPLE[0]))
    earth_km = astrometric_from_mars_j2000_km("earth", t_s)
    assert r["one_way_light_time_s"] == pytest.approx(np.linalg.norm(earth_km) / C_KM_S, abs=1e-3)
    # three days before Spirit landed: 9 min 26 s (3 to 22 minutes: Mishkin, Limonadi,
    # Laubach and Bass 2006)
    assert r["one_way_light_time_s"] == pytest.approx(565.84, abs=0.01)


def test_the_text_shows_the_light_time_in_minutes_and_seconds(
    capsys: pytest.CaptureFixture[str],
) -> None:
    r = ephem_report(*EXAMPLE, "spirit")
    print_ephem(r, False)
    lines = capsys.readouterr().out.splitlines()
    assert "one_way_light_time: 9 min 25.8 s" in lines
    assert lines.index("sol: 1") < lines.index("one_way_light_time: 9 min 25.8 s")
    assert lines.index("one_way_light_time: 9 min 25.8 s") < lines.index("mars24:")
    print_ephem(r, True)
    assert json.loads(capsys.readouterr().out)["one_way_light_time_s"] == r["one_way_light_time_s"]
    assert minutes_seconds(1334.96) == "22 min 15.0 s"
    assert minutes_seconds(179.99) == "3 min 0.0 s"


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
