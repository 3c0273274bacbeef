"""Mars time: UTC <-> TT, the Mars24 algorithm, and MER sol numbering.

Implements the Mars24 algorithm of Allison and McEwen (2000, Planet. Space Sci. 48,
215-235) as documented step by step, with its current constants, on NASA GISS's page
"Mars24 Sunclock -- Algorithm and Worked Examples" (constants copied into
docs/REFERENCES.md, "Mars time and the Sun"). Each line of math carries its step
number, A-1 .. D-6.

Time scales (docs/CONVENTIONS.md):

- ``utc``: a ``datetime``; aware ones are converted to UTC, naive ones are taken as UTC.
  Python's datetimes, like Mars24's Java milliseconds, do not count leap seconds, so an
  instant inside a leap second cannot be represented (it has never mattered for MER).
- ``t_s``: seconds of TT since J2000 = 2000-01-01T12:00:00 TT. ``TT - UTC = 32.184 s +
  (TAI - UTC)``, the leap-second count of the table below (A-4).
- ``msd``: Mars Sol Date (C-2); ``mst_h``, ``lmst_h``, ``ltst_h``: hours of a 24-hour Mars
  clock at the prime meridian (Airy-0), the local mean and the local true solar time.

Mars24 angles are degrees with longitude ``Λ`` positive West, as on the GISS page; its
latitude is planetographic. Mars24's solar declination (D-1) is planetographic and its
zenith formula (D-5) spherical: an almanac good to a few tenths of a degree. The
rigorous sun direction is ``sim.world.mars_frames`` (ephemeris, IAU rotation, ellipsoid).

MER sols: the landing sol is sol 1 and sols turn over at local mean midnight (LMST 00:00)
at the landing site. (MER's own mission clocks were hybrids, mean-solar clocks phased to
true solar time near sol 45, about 41 Mars minutes off LMST at Spirit's site; JPL's
published sol boundaries fall correspondingly later than the ones computed here.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.errors import InputError

FloatArray = NDArray[np.float64]

SECONDS_PER_DAY = 86_400.0
JD_UNIX_EPOCH = 2_440_587.5  # JD of 1970-01-01T00:00:00
JD_J2000 = 2_451_545.0  # JD of 2000-01-01T12:00:00 TT
TT_MINUS_TAI_S = 32.184  # exact, by definition of TT
SOL_PER_DAY_RATIO = 1.0274912517  # Earth days per mean solar day of Mars (C-2)
SOL_S = SOL_PER_DAY_RATIO * SECONDS_PER_DAY  # 88775.244 s, one Mars mean solar day

J2000_UTC = datetime(2000, 1, 1, 12, 0, 0, tzinfo=UTC)  # the J2000 epoch's calendar time
FIRST_UTC = datetime(1972, 1, 1, tzinfo=UTC)  # UTC with whole leap seconds begins here

# TAI - UTC (s) from each date on (IERS Bulletin C). 37 s since 2017-01-01; no leap second
# has been announced since. Dates before 1972 (rubber seconds) are rejected.
LEAP_SECONDS: tuple[tuple[datetime, int], ...] = tuple(
    (datetime(y, m, 1, tzinfo=UTC), n)
    for y, m, n in (
        (1972, 1, 10),
        (1972, 7, 11),
        (1973, 1, 12),
        (1974, 1, 13),
        (1975, 1, 14),
        (1976, 1, 15),
        (1977, 1, 16),
        (1978, 1, 17),
        (1979, 1, 18),
        (1980, 1, 19),
        (1981, 7, 20),
        (1982, 7, 21),
        (1983, 7, 22),
        (1985, 7, 23),
        (1988, 1, 24),
        (1990, 1, 25),
        (1991, 1, 26),
        (1992, 7, 27),
        (1993, 7, 28),
        (1994, 7, 29),
        (1996, 1, 30),
        (1997, 7, 31),
        (1999, 1, 32),
        (2006, 1, 33),
        (2009, 1, 34),
        (2012, 7, 35),
        (2015, 7, 36),
        (2017, 1, 37),
    )
)

# B-3: amplitude (deg), period (Julian years) and phase (deg) of the seven perturbers.
_PBS_A_DEG = np.array([0.0071, 0.0057, 0.0039, 0.0037, 0.0021, 0.0020, 0.0018])
_PBS_TAU_YR = np.array([2.2353, 2.7543, 1.1177, 15.7866, 2.1354, 2.4694, 32.8493])
_PBS_PHI_DEG = np.array([49.409, 168.173, 191.837, 21.736, 15.704, 95.528, 49.095])


def as_utc(utc: datetime) -> datetime:
    """Return ``utc`` as an aware UTC datetime (naive input is taken as UTC); validate it."""
    if not isinstance(utc, datetime):
        raise InputError("utc", f"expected a datetime, got {type(utc).__name__}")
    out = utc.replace(tzinfo=UTC) if utc.tzinfo is None else utc.astimezone(UTC)
    if out < FIRST_UTC:
        raise InputError("utc", f"{out.isoformat()} is before 1972-01-01 (no leap-second UTC)")
    return out


def tt_minus_utc_s(utc: datetime) -> float:
    """``TT - UTC`` in seconds at ``utc``: 32.184 s plus the leap seconds (A-4).

    >>> tt_minus_utc_s(datetime(2004, 1, 3))
    64.184
    """
    when = as_utc(utc)
    tai_minus_utc = 0
    for start, n in LEAP_SECONDS:
        if when >= start:
            tai_minus_utc = n
        else:
            break
    return TT_MINUS_TAI_S + tai_minus_utc


def utc_to_t_s(utc: datetime) -> float:
    """TT seconds since J2000 at ``utc`` (A-5, A-6 in seconds).

    >>> round(utc_to_t_s(datetime(2000, 1, 1, 11, 58, 55, 816000)), 6)
    0.0
    """
    when = as_utc(utc)
    return (when - J2000_UTC).total_seconds() + tt_minus_utc_s(when)


def t_s_to_utc(t_s: float) -> datetime:
    """The aware UTC datetime of TT seconds since J2000 ``t_s`` (inverse of ``utc_to_t_s``)."""
    if not math.isfinite(t_s):
        raise InputError("t_s", f"must be finite, got {t_s!r}")
    guess = J2000_UTC + timedelta(seconds=t_s - TT_MINUS_TAI_S - LEAP_SECONDS[-1][1])
    if guess < FIRST_UTC:
        raise InputError("t_s", f"{t_s} s is before 1972-01-01 UTC")
    # Two fixed-point passes settle the leap-second count (it changes by at most 1 s).
    for _ in range(2):
        guess = J2000_UTC + timedelta(seconds=t_s - tt_minus_utc_s(guess))
    return guess


@dataclass(frozen=True)
class Mars24:
    """All intermediate and final quantities of Mars24 at one instant and site.

    Angles in degrees, times of day in Mars hours, ``Λ`` (``lon_west_deg``) West,
    latitude planetographic. Field comments give the GISS step.
    """

    jd_ut: float  # A-2, Julian Date (UT)
    tt_minus_utc_s: float  # A-4, s
    jd_tt: float  # A-5, Julian Date (TT)
    delta_t_j2000_d: float  # A-6, days of TT since J2000
    mean_anomaly_deg: float  # B-1, M, in [0, 360)
    alpha_fms_deg: float  # B-2, angle of the fictitious mean sun, in [0, 360)
    pbs_deg: float  # B-3, perturbers
    nu_minus_m_deg: float  # B-4, equation of centre
    ls_deg: float  # B-5, areocentric solar longitude, in [0, 360)
    eot_deg: float  # C-1, equation of time (degrees; /15 gives hours)
    msd: float  # C-2, Mars Sol Date
    mst_h: float  # C-2, mean solar time at the prime meridian
    lat_deg: float  # the site, planetographic
    lon_west_deg: float  # the site, Λ
    lmst_h: float  # C-3
    ltst_h: float  # C-4
    subsolar_lon_west_deg: float  # C-5, Λs
    solar_declination_deg: float  # D-1, planetographic
    heliocentric_distance_au: float  # D-2
    hour_angle_deg: float  # D-5, H = Λ - Λs, in (-180, 180]
    sun_zenith_deg: float  # D-5, Z
    sun_elev_deg: float  # 90 - Z
    sun_azimuth_deg: float  # D-6, clockwise from North, in [0, 360)


def _check_site(lat_deg: float, lon_west_deg: float) -> None:
    if not (math.isfinite(lat_deg) and -90.0 <= lat_deg <= 90.0):
        raise InputError("lat_deg", f"must be in [-90, 90], got {lat_deg!r}")
    if not math.isfinite(lon_west_deg):
        raise InputError("lon_west_deg", f"must be finite, got {lon_west_deg!r}")


def mars24(utc: datetime, lat_deg: float = 0.0, lon_west_deg: float = 0.0) -> Mars24:
    """Run Mars24 (steps A-1 .. D-6) for ``utc`` at planetographic ``lat_deg``, West ``Λ``.

    >>> m = mars24(datetime(2000, 1, 6))
    >>> round(m.ls_deg, 5), round(m.mst_h, 5)
    (277.18759, 23.99425)
    """
    when = as_utc(utc)
    _check_site(lat_deg, lon_west_deg)
    millis = (when - datetime(1970, 1, 1, tzinfo=UTC)) / timedelta(milliseconds=1)
    jd_ut = JD_UNIX_EPOCH + millis / 8.64e7
    dtt = tt_minus_utc_s(when)
    return _mars24_from_jd(jd_ut, dtt, lat_deg, lon_west_deg)


def mars24_at_t_s(t_s: float, lat_deg: float = 0.0, lon_west_deg: float = 0.0) -> Mars24:
    """Mars24 at TT seconds since J2000 ``t_s`` (same as ``mars24(t_s_to_utc(t_s), ...)``)."""
    return mars24(t_s_to_utc(t_s), lat_deg, lon_west_deg)


def _mars24_from_jd(jd_ut: float, dtt_s: float, lat_deg: float, lon_west_deg: float) -> Mars24:
    jd_tt = jd_ut + dtt_s / SECONDS_PER_DAY
    dt = jd_tt - JD_J2000
    M = 19.3871 + 0.52402073 * dt  # B-1
    alpha_fms = 270.3871 + 0.524038496 * dt  # B-2
    pbs = float(  # B-3
        np.sum(_PBS_A_DEG * np.cos(np.radians(0.985626 * dt / _PBS_TAU_YR + _PBS_PHI_DEG)))
    )
    m_rad = math.radians(M)
    nu_m = (  # B-4
        (10.691 + 3.0e-7 * dt) * math.sin(m_rad)
        + 0.623 * math.sin(2 * m_rad)
        + 0.050 * math.sin(3 * m_rad)
        + 0.005 * math.sin(4 * m_rad)
        + 0.0005 * math.sin(5 * m_rad)
        + pbs
    )
    ls = (alpha_fms + nu_m) % 360.0  # B-5
    ls_rad = math.radians(ls)
    eot = (  # C-1
        2.861 * math.sin(2 * ls_rad)
        - 0.071 * math.sin(4 * ls_rad)
        + 0.002 * math.sin(6 * ls_rad)
        - nu_m
    )
    msd = (jd_tt - 2_451_549.5) / SOL_PER_DAY_RATIO + 44_796.0 - 0.0009626  # C-2
    mst = (24.0 * msd) % 24.0  # C-2
    lmst = (mst - lon_west_deg / 15.0) % 24.0  # C-3
    ltst = (lmst + eot / 15.0) % 24.0  # C-4
    subsolar = (15.0 * mst + eot + 180.0) % 360.0  # C-5, Λs West
    dec = math.degrees(math.asin(0.42565 * math.sin(ls_rad))) + 0.25 * math.sin(ls_rad)  # D-1
    r_au = 1.52367934 * (  # D-2
        1.00436
        - 0.09309 * math.cos(m_rad)
        - 0.004336 * math.cos(2 * m_rad)
        - 0.00031 * math.cos(3 * m_rad)
        - 0.00003 * math.cos(4 * m_rad)
    )
    H = (lon_west_deg - subsolar + 180.0) % 360.0 - 180.0  # D-5, hour angle
    h_rad, d_rad, p_rad = math.radians(H), math.radians(dec), math.radians(lat_deg)
    cos_z = math.sin(d_rad) * math.sin(p_rad) + math.cos(d_rad) * math.cos(p_rad) * math.cos(h_rad)
    Z = math.degrees(math.acos(min(1.0, max(-1.0, cos_z))))  # D-5
    az = math.degrees(  # D-6, clockwise from North
        math.atan2(
            math.sin(h_rad),
            math.cos(p_rad) * math.tan(d_rad) - math.sin(p_rad) * math.cos(h_rad),
        )
    )
    return Mars24(
        jd_ut=jd_ut,
        tt_minus_utc_s=dtt_s,
        jd_tt=jd_tt,
        delta_t_j2000_d=dt,
        mean_anomaly_deg=M % 360.0,
        alpha_fms_deg=alpha_fms % 360.0,
        pbs_deg=pbs,
        nu_minus_m_deg=nu_m,
        ls_deg=ls,
        eot_deg=eot,
        msd=msd,
        mst_h=mst,
        lat_deg=lat_deg,
        lon_west_deg=lon_west_deg,
        lmst_h=lmst,
        ltst_h=ltst,
        subsolar_lon_west_deg=subsolar,
        solar_declination_deg=dec,
        heliocentric_distance_au=r_au,
        hour_angle_deg=H,
        sun_zenith_deg=Z,
        sun_elev_deg=90.0 - Z,
        sun_azimuth_deg=az % 360.0,
    )


def msd_from_t_s(t_s: ArrayLike) -> FloatArray:
    """Mars Sol Date at TT seconds since J2000 ``t_s`` (C-2); broadcasts, cheap.

    >>> round(float(msd_from_t_s(utc_to_t_s(datetime(2000, 1, 6)))), 5)
    44795.99976
    """
    jd_tt = JD_J2000 + np.asarray(t_s, dtype=float) / SECONDS_PER_DAY  # A-6 inverted
    out: FloatArray = (jd_tt - 2_451_549.5) / SOL_PER_DAY_RATIO + 44_796.0 - 0.0009626  # C-2
    return out


def lmst_h_from_t_s(t_s: ArrayLike, lon_west_deg: float) -> FloatArray:
    """Local mean solar time (Mars hours, [0, 24)) at West longitude ``Λ`` (C-2, C-3)."""
    out: FloatArray = (24.0 * msd_from_t_s(t_s) - lon_west_deg / 15.0) % 24.0
    return out


@dataclass(frozen=True)
class Mission:
    """A MER landing: UTC of landing and the site, planetographic latitude, East longitude."""

    name: str
    landing_utc: datetime
    lat_deg: float
    lon_east_deg: float

    @property
    def lon_west_deg(self) -> float:
        """The landing longitude as Mars24's West ``Λ`` in [0, 360)."""
        return (360.0 - self.lon_east_deg) % 360.0


# Landing UTC and sites (planetographic latitude, East longitude) as the project specifies.
MISSIONS: dict[str, Mission] = {
    "spirit": Mission("spirit", datetime(2004, 1, 4, 4, 35, tzinfo=UTC), -14.57, 175.48),
    "opportunity": Mission("opportunity", datetime(2004, 1, 25, 5, 5, tzinfo=UTC), -1.95, 354.47),
}


def get_mission(mission: str) -> Mission:
    """The ``Mission`` called ``mission`` (case-insensitive); ``InputError`` if unknown."""
    if not isinstance(mission, str) or mission.strip().lower() not in MISSIONS:
        raise InputError("mission", f"unknown mission {mission!r}; known: {sorted(MISSIONS)}")
    return MISSIONS[mission.strip().lower()]


def _local_sol_date(m: Mission, t_s: ArrayLike) -> FloatArray:
    # The local mean solar date at the landing site: its fraction is LMST / 24 (C-3).
    out: FloatArray = msd_from_t_s(t_s) - m.lon_west_deg / 360.0
    return out


def sol_number_t_s(mission: str, t_s: ArrayLike) -> NDArray[np.int64]:
    """MER sol number at TT seconds ``t_s`` (broadcasts): 1 on the landing sol.

    Sols before landing come out 0, -1, ...; the sol turns at LMST 00:00 at the site.
    """
    m = get_mission(mission)
    landing = math.floor(float(_local_sol_date(m, utc_to_t_s(m.landing_utc))))
    out: NDArray[np.int64] = (np.floor(_local_sol_date(m, t_s)) - landing + 1).astype(np.int64)
    return out


def sol_number(mission: str, utc: datetime) -> int:
    """MER sol number of ``mission`` ("spirit" or "opportunity") at ``utc``; landing = sol 1.

    >>> sol_number("spirit", datetime(2004, 1, 4, 4, 35))
    1
    """
    m = get_mission(mission)
    return int(sol_number_t_s(m.name, utc_to_t_s(utc)))


def t_s_for_sol_lmst(mission: str, sol: int, lmst_h: float) -> float:
    """TT seconds from J2000 when the LMST at ``mission``'s landing site reads ``lmst_h``
    on MER sol ``sol``: the inverse of ``sol_number_t_s`` and ``lmst_h_from_t_s`` (C-2, C-3).

    >>> t = t_s_for_sol_lmst("spirit", 100, 10.5)
    >>> lmst = float(lmst_h_from_t_s(t, MISSIONS["spirit"].lon_west_deg))
    >>> int(sol_number_t_s("spirit", t)), round(lmst, 6)
    (100, 10.5)
    """
    m = get_mission(mission)
    if not (math.isfinite(lmst_h) and 0.0 <= lmst_h < 24.0):
        raise InputError("lmst_h", f"must be in [0, 24), got {lmst_h!r}")
    landing = math.floor(float(_local_sol_date(m, utc_to_t_s(m.landing_utc))))
    msd = landing + (sol - 1) + lmst_h / 24.0 + m.lon_west_deg / 360.0
    jd_tt = (msd - 44_796.0 + 0.0009626) * SOL_PER_DAY_RATIO + 2_451_549.5  # C-2 inverted
    return (jd_tt - JD_J2000) * SECONDS_PER_DAY
