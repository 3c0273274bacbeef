"""Command limits on time: a drive's time budget and its time-of-day limit.

A MER drive carried limits of its own besides the distance (Biesiadecki and Maimone 2006
sec. 3, "command limits"): it stopped when it had not reached its goal within its time, or
when the local solar time passed the end of the driving window the ground had planned.
The flight software keeps its own clock (``t_s``, TT seconds since J2000), so Local Mean
Solar Time here is the flight software's own arithmetic of the Mars24 algorithm (Allison
and McEwen 2000; steps A-6, C-2, C-3): the Mars Sol Date from the TT Julian date, the Mars
Coordinated Time, and the site's longitude.

>>> round(lmst_h(0.0, 0.0), 4)  # J2000 TT at the prime meridian
14.8665
"""

from __future__ import annotations

import math

J2000_JD_TT = 2451545.0  # Allison and McEwen 2000, step A-6
SOL_PER_DAY = 1.0 / 1.0274912517  # Earth days per mean sol, inverted (step C-2)


def mars_sol_date(t_s: float) -> float:
    """The Mars Sol Date of ``t_s`` (TT seconds since J2000; step C-2)."""
    jd_tt = J2000_JD_TT + t_s / 86400.0
    return (jd_tt - 2451549.5) * SOL_PER_DAY + 44796.0 - 0.0009626


def lmst_h(t_s: float, lon_east_rad: float) -> float:
    """Local Mean Solar Time at East longitude ``lon_east_rad``, hours in [0, 24)."""
    if not (math.isfinite(t_s) and math.isfinite(lon_east_rad)):
        raise ValueError("t_s, lon_east_rad: must be finite")
    mtc_h = (24.0 * mars_sol_date(t_s)) % 24.0  # step C-3
    return (mtc_h + math.degrees(lon_east_rad) / 15.0) % 24.0


def past_time_of_day(start_lmst_h: float, now_lmst_h: float, limit_lmst_h: float) -> bool:
    """Whether, on a drive that began at ``start_lmst_h``, the time ``now_lmst_h`` has
    reached ``limit_lmst_h`` (the first time the clock comes to it after the start)."""
    span = (limit_lmst_h - start_lmst_h) % 24.0
    return (now_lmst_h - start_lmst_h) % 24.0 >= span
