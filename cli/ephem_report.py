"""The report behind ``roverops ephem``: Mars time, and the Sun and Earth seen from a site.

One UTC instant and one site give three answers side by side: Mars24's almanac (Allison and
McEwen 2000, ``sim.world.marsclock``), the truth (DE421, Folkner, Williams and Boggs 2008, with
the IAU 2009 rotation of Archinal et al. 2011 and the IAU/IAG 2000 ellipsoid,
``sim.world.mars_frames``) and the onboard conic approximation (Standish's Keplerian elements,
``estimation.ivp``). Angles in degrees (this is an edge of the system); vectors are unit
vectors in the Local-Level frame (N, E, Down). Beside them, the one-way light time from
Earth's centre to Mars' at that instant (``sim.world.light_time``, from the same DE421): the
delay every command and every frame crosses (3 to 22 minutes, Mishkin, Limonadi, Laubach
and Bass 2006), in seconds in the JSON and in minutes and seconds in the text
(``print_ephem``).

The site is a planetographic latitude and a West longitude in [0, 360), Mars24's
convention. Every bad input raises ``InputError`` naming ``utc``, ``lat_deg``,
``lon_west_deg`` or ``mission``.
"""

from __future__ import annotations

import math
import re
from datetime import UTC, datetime
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cli.output import print_result
from estimation import ivp
from sim.errors import InputError
from sim.world.ephemeris import check_t_s
from sim.world.light_time import one_way_light_time_s
from sim.world.mars_frames import azimuth_rad, earth_ll_truth, elevation_rad, sun_ll_truth
from sim.world.marsclock import mars24, sol_number, utc_to_t_s

# ISO 8601 calendar date and time, optional fraction, optional "Z" or "+00:00". Other
# offsets are refused rather than converted: the field is called utc.
_ISO_UTC = re.compile(
    r"[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}(:[0-9]{2}(\.[0-9]{1,6})?)?(Z|\+00:00)?"
)


def parse_utc(utc: str) -> datetime:
    """Parse an ISO 8601 UTC string (``2004-01-03T13:46:31``, optional ``Z``/``+00:00``).

    >>> parse_utc("2004-01-03T13:46:31Z").isoformat()
    '2004-01-03T13:46:31+00:00'
    """
    if not isinstance(utc, str) or _ISO_UTC.fullmatch(utc.strip()) is None:
        raise InputError(
            "utc",
            f"expected ISO 8601 UTC like 2004-01-03T13:46:31 (optional Z or +00:00), got {utc!r}",
        )
    text = utc.strip()
    text = text[:-1] if text.endswith("Z") else text
    if re.search(r"T\d\d:\d\d:60", text):
        raise InputError("utc", f"leap seconds (:60) cannot be represented; got {utc!r}")
    try:
        when = datetime.fromisoformat(text)
    except ValueError as err:
        raise InputError("utc", f"not a valid date and time: {utc!r} ({err})") from None
    return when.replace(tzinfo=UTC) if when.tzinfo is None else when.astimezone(UTC)


def _number(name: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(name, f"must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out):
        raise InputError(name, f"must be finite, got {value!r}")
    return out


def _directions(v_ll: NDArray[np.float64], prefix: str) -> dict[str, Any]:
    return {
        f"{prefix}_elev_deg": math.degrees(float(elevation_rad(v_ll))),
        f"{prefix}_azimuth_deg": math.degrees(float(azimuth_rad(v_ll))),
    }


def _section(sun: NDArray[np.float64], earth: NDArray[np.float64]) -> dict[str, Any]:
    return {
        **_directions(sun, "sun"),
        **_directions(earth, "earth"),
        "sun_ll": [float(x) for x in sun],
        "earth_ll": [float(x) for x in earth],
    }


def ephem_report(
    utc: str, lat_deg: float, lon_west_deg: float, mission: str | None
) -> dict[str, Any]:
    """The ``roverops ephem`` JSON object for ``utc`` at the site (see module docstring).

    Keys: ``msd``, ``mst_h``, ``lmst_h``, ``ltst_h``, ``ls_deg``, ``sol`` (only with a
    mission), ``one_way_light_time_s`` (Earth's centre to Mars' centre, arriving at
    ``utc``), and sections ``mars24`` (``sun_elev_deg``, ``sun_azimuth_deg``), ``truth``
    and ``ivp`` (``sun_elev_deg``, ``sun_azimuth_deg``, ``earth_elev_deg``,
    ``earth_azimuth_deg``, ``sun_ll`` and ``earth_ll`` as 3-lists).
    """
    when = parse_utc(utc)
    lat = _number("lat_deg", lat_deg)
    if not -90.0 <= lat <= 90.0:
        raise InputError("lat_deg", f"must be in [-90, 90], got {lat_deg!r}")
    lon_w = _number("lon_west_deg", lon_west_deg)
    if not 0.0 <= lon_w < 360.0:
        raise InputError("lon_west_deg", f"must be in [0, 360), got {lon_west_deg!r}")
    if mission is not None and not isinstance(mission, str):
        raise InputError("mission", f"must be a mission name, got {mission!r}")

    t_s = check_t_s(utc_to_t_s(when))  # both InputError("utc", ...) when out of range
    m24 = mars24(when, lat, lon_w)
    lat_rad = math.radians(lat)
    lon_east_rad = math.radians((360.0 - lon_w) % 360.0)

    report: dict[str, Any] = {
        "msd": m24.msd,
        "mst_h": m24.mst_h,
        "lmst_h": m24.lmst_h,
        "ltst_h": m24.ltst_h,
        "ls_deg": m24.ls_deg,
    }
    if mission is not None:
        report["sol"] = sol_number(mission, when)
    report["one_way_light_time_s"] = float(one_way_light_time_s(t_s))
    report["mars24"] = {"sun_elev_deg": m24.sun_elev_deg, "sun_azimuth_deg": m24.sun_azimuth_deg}
    report["truth"] = _section(
        sun_ll_truth(t_s, lat_rad, lon_east_rad), earth_ll_truth(t_s, lat_rad, lon_east_rad)
    )
    report["ivp"] = _section(
        ivp.sun_ll(t_s, lat_rad, lon_east_rad), ivp.earth_ll(t_s, lat_rad, lon_east_rad)
    )
    return report


def minutes_seconds(duration_s: float) -> str:
    """A duration as minutes and seconds to a tenth, as the text report shows a light time.

    >>> minutes_seconds(567.77), minutes_seconds(59.96)
    ('9 min 27.8 s', '1 min 0.0 s')
    """
    tenths = round(duration_s * 10.0)
    minutes, rest = divmod(tenths, 600)
    return f"{minutes} min {rest / 10.0:.1f} s"


def print_ephem(result: dict[str, Any], as_json: bool) -> None:
    """``roverops ephem``'s report: JSON with ``--json``; else ``print_result``'s lines, the
    light time in minutes and seconds."""
    if as_json or "one_way_light_time_s" not in result:
        print_result(result, as_json)
        return
    shown = {k: v for k, v in result.items() if k != "one_way_light_time_s"}
    tail = {k: shown.pop(k) for k in list(shown) if isinstance(shown[k], dict)}
    print_result(shown, False)
    print(f"one_way_light_time: {minutes_seconds(result['one_way_light_time_s'])}")
    print_result(tail, False)
