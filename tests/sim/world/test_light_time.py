"""Light time between Earth and Mars (``sim.world.light_time``): against the light-time
equations solved independently (jplephem read here, scipy's ``brentq`` on each equation),
the published range of 3 to 22 minutes one way (Mishkin, Limonadi, Laubach and Bass 2006),
and the invariants that tie the three functions together."""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Any

import numpy as np
import pytest
from jplephem.spk import SPK
from scipy.optimize import brentq

from sim.errors import InputError
from sim.world.ephemeris import astrometric_from_mars_j2000_km, coverage_t_s, de421_path
from sim.world.light_time import (
    downlink_arrival_t_s,
    one_way_light_time_s,
    uplink_arrival_t_s,
)
from sim.world.marsclock import utc_to_t_s

C_KM_S = 299_792.458  # the speed of light, exact (SI)
JD_J2000 = 2_451_545.0
DAY_S = 86_400.0
# 2004 (the landings), near opposition (2018-07-27), near conjunction (2021-10-08), 2030
INSTANTS = [
    datetime(2004, 1, 4, 4, 35, tzinfo=UTC),
    datetime(2018, 7, 27, tzinfo=UTC),
    datetime(2021, 10, 8, tzinfo=UTC),
    datetime(2030, 6, 1, tzinfo=UTC),
]


@pytest.fixture(scope="module")
def kernel() -> Any:
    spk = SPK.open(str(de421_path()))
    yield spk
    spk.close()


def _earth_km(kernel: Any, t_s: float) -> np.ndarray:
    jd = JD_J2000 + t_s / DAY_S  # SSB -> Earth-Moon barycentre -> Earth
    return np.asarray(kernel[0, 3].compute(jd) + kernel[3, 399].compute(jd), dtype=float)


def _mars_km(kernel: Any, t_s: float) -> np.ndarray:
    jd = JD_J2000 + t_s / DAY_S  # SSB -> Mars barycentre -> Mars
    return np.asarray(kernel[0, 4].compute(jd) + kernel[4, 499].compute(jd), dtype=float)


def _tau_at_mars(kernel: Any, t_s: float) -> float:
    """Root of ``f(τ) = c τ - |x_Mars(t) - x_Earth(t - τ)|`` between 2 and 30 minutes."""
    mars = _mars_km(kernel, t_s)
    return float(
        brentq(
            lambda tau: C_KM_S * tau - np.linalg.norm(mars - _earth_km(kernel, t_s - tau)),
            120.0,
            1800.0,
            xtol=1e-9,
        )
    )


@pytest.mark.parametrize("when", INSTANTS, ids=lambda d: d.date().isoformat())
def test_one_way_light_time_matches_brentq_on_jplephem(kernel: Any, when: datetime) -> None:
    t = utc_to_t_s(when)
    assert float(one_way_light_time_s(t)) == pytest.approx(_tau_at_mars(kernel, t), abs=1e-6)


@pytest.mark.parametrize("when", INSTANTS, ids=lambda d: d.date().isoformat())
def test_uplink_arrival_matches_brentq_on_jplephem(kernel: Any, when: datetime) -> None:
    t_radiated = utc_to_t_s(when)
    expected = brentq(  # t_a - τ(t_a) - t_radiated = 0, τ itself solved by brentq
        lambda t_a: t_a - _tau_at_mars(kernel, t_a) - t_radiated,
        t_radiated + 120.0,
        t_radiated + 1800.0,
        xtol=1e-8,
    )
    assert uplink_arrival_t_s(t_radiated) == pytest.approx(expected, abs=1e-5)


@pytest.mark.parametrize("when", INSTANTS, ids=lambda d: d.date().isoformat())
def test_downlink_arrival_matches_brentq_on_jplephem(kernel: Any, when: datetime) -> None:
    t_sent = utc_to_t_s(when)
    mars = _mars_km(kernel, t_sent)
    tau = brentq(
        lambda tau: C_KM_S * tau - np.linalg.norm(_earth_km(kernel, t_sent + tau) - mars),
        120.0,
        1800.0,
        xtol=1e-9,
    )
    assert downlink_arrival_t_s(t_sent) == pytest.approx(t_sent + tau, abs=1e-5)


def test_agrees_with_the_light_time_the_ephemeris_applies_to_earths_direction() -> None:
    # sim.world.ephemeris solves the same equation (three passes) for Earth's direction
    t = utc_to_t_s(INSTANTS[0]) + np.arange(5.0) * 3.0e6
    distance_s = np.linalg.norm(astrometric_from_mars_j2000_km("earth", t), axis=-1) / C_KM_S
    assert np.max(np.abs(one_way_light_time_s(t) - distance_s)) < 1e-6


def test_the_published_range_3_to_22_minutes_over_2004_2030() -> None:
    # Mishkin, Limonadi, Laubach and Bass 2006: 3 to 22 minutes one way; daily over 2004-2030
    # the closest approach (2018's opposition, 57.6 million km) and the farthest
    # (a conjunction, ~401 million km) bound it
    days = np.arange(utc_to_t_s(datetime(2004, 1, 1)), utc_to_t_s(datetime(2031, 1, 1)), DAY_S)
    minutes = one_way_light_time_s(days) / 60.0
    assert minutes.shape == days.shape
    assert 3.0 < minutes.min() < 3.3
    assert 22.0 < minutes.max() < 22.4
    # a conjunction (the farthest) once a synodic period, 780 days on average (Mars' orbit
    # makes single ones 750-900 days apart): 12 or 13 of them in these 27 years
    peaks = np.flatnonzero((minutes[1:-1] > minutes[:-2]) & (minutes[1:-1] >= minutes[2:]))
    assert 12 <= peaks.size <= 13
    assert (peaks[-1] - peaks[0]) / (peaks.size - 1) == pytest.approx(780.0, abs=10.0)


def test_vectorises_over_any_shape() -> None:
    t0 = utc_to_t_s(datetime(2004, 1, 4))
    grid = t0 + np.arange(6.0).reshape(2, 3) * 1.0e6
    taus = one_way_light_time_s(grid)
    assert taus.shape == (2, 3)
    assert taus[1, 2] == float(one_way_light_time_s(grid[1, 2]))
    assert np.ndim(one_way_light_time_s(t0)) == 0


@pytest.mark.parametrize("when", INSTANTS, ids=lambda d: d.date().isoformat())
def test_the_three_agree(when: datetime) -> None:
    t = utc_to_t_s(when)
    arrival = uplink_arrival_t_s(t)
    assert arrival - t == pytest.approx(float(one_way_light_time_s(arrival)), abs=1e-6)
    # the way back differs by the range's change over the crossing: < 20 km/s x 22 min / c
    assert abs((downlink_arrival_t_s(t) - t) - float(one_way_light_time_s(t))) < 0.2
    # a reply: Mars hears at `arrival` and answers at once; Earth hears it 2τ later
    back = downlink_arrival_t_s(arrival)
    assert back - t == pytest.approx(2.0 * (arrival - t), abs=0.2)


@pytest.mark.parametrize(
    "bad", [float("nan"), float("inf"), -1.0e10, 1.7e9, True, "2004-01-04"], ids=repr
)
def test_bad_times_name_the_argument(bad: Any) -> None:
    with pytest.raises(InputError) as err:
        one_way_light_time_s(bad)
    assert err.value.parameter == "t_s"
    with pytest.raises(InputError) as err:
        uplink_arrival_t_s(bad)
    assert err.value.parameter == "t_radiated_s"
    with pytest.raises(InputError) as err:
        downlink_arrival_t_s(bad)
    assert err.value.parameter == "t_sent_s"
    with pytest.raises(InputError):
        one_way_light_time_s(np.array([0.0, math.nan]))


def test_a_signal_that_would_arrive_after_the_ephemeris_ends_is_refused() -> None:
    _, last = coverage_t_s()
    assert float(one_way_light_time_s(last)) > 0.0  # its light left Earth inside DE421
    with pytest.raises(InputError) as err:
        uplink_arrival_t_s(last - 60.0)  # it reaches Mars after the end of the coverage
    assert err.value.parameter == "t_radiated_s"
    with pytest.raises(InputError) as err:
        downlink_arrival_t_s(last - 60.0)
    assert err.value.parameter == "t_sent_s"
