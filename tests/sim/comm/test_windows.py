"""The windows the ground predicts (``sim.comm.windows``): relay passes against a brute
search of the orbiter's elevation every second (computed here from the ellipsoid's normal),
the sessions against the LMST clock and Earth's elevation, and the invariants of the
answer (whole windows, sorted, overlapping the span, the same from any query)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from sim.comm.plan import CommPlan
from sim.comm.windows import (
    MAX_SPAN_S,
    Window,
    comm_windows,
    sol_index,
    sol_start_t_s,
)
from sim.errors import InputError
from sim.sensors.orbiter import ORBIT_EPOCH, KeplerOrbit, RelayOrbiter
from sim.world.mars_frames import earth_ll_truth, elevation_rad, site_mf_m
from sim.world.marsclock import MISSIONS, SOL_S, lmst_h_from_t_s, t_s_for_sol_lmst, utc_to_t_s

SPIRIT = MISSIONS["spirit"]
OPPORTUNITY = MISSIONS["opportunity"]
PLAN = CommPlan()
T0 = t_s_for_sol_lmst("spirit", 30, 0.0)  # Spirit's sol 30 opens (LMST 00:00 at its site)
# Opportunity's sols 2000-2002: Earth rises from -2.5° to 12° over the 09:00 LMST session
T_LOW_EARTH = t_s_for_sol_lmst("opportunity", 2000, 0.0)
HOUR_S_PER_LMST_H = SOL_S / 24.0


def _site(lat_deg: float, lon_east_deg: float) -> tuple[np.ndarray, np.ndarray]:
    lat, lon = math.radians(lat_deg), math.radians(lon_east_deg)
    # the outward ellipsoid normal at a planetographic latitude, written out here
    up = np.array([math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)])
    return site_mf_m(lat, lon), up


def _orbiter_elev_deg(t_s: np.ndarray, lat_deg: float, lon_east_deg: float) -> np.ndarray:
    """The orbiter's elevation: the angle of the line of sight above the horizon plane."""
    site, up = _site(lat_deg, lon_east_deg)
    orbiter = RelayOrbiter(KeplerOrbit(epoch_t_s=utc_to_t_s(ORBIT_EPOCH)))
    d = orbiter.position_mf_m(t_s) - site
    return np.degrees(np.arcsin(d @ up / np.linalg.norm(d, axis=-1)))


def _earth_elev_deg(t_s: Any, lat_deg: float, lon_east_deg: float) -> np.ndarray:
    v = earth_ll_truth(t_s, math.radians(lat_deg), math.radians(lon_east_deg))
    return np.degrees(elevation_rad(v))


def _lmst_h(t_s: float, lon_east_deg: float) -> float:
    return float(lmst_h_from_t_s(t_s, (360.0 - lon_east_deg) % 360.0))


@pytest.fixture(scope="module")
def spirit_ten_sols() -> list[Window]:
    return comm_windows(SPIRIT.lat_deg, SPIRIT.lon_east_deg, PLAN, T0, T0 + 10 * SOL_S)


def test_relay_passes_a_sol_and_their_lengths(spirit_ten_sols: list[Window]) -> None:
    # Spirit's site, sols 30-39: a polar orbit 400 km up passes 1 to 4 times a sol (2 or 3
    # mostly), each up to 12 minutes over 10°
    relay = [w for w in spirit_ten_sols if w.kind == "relay"]
    per_sol = np.bincount(
        [
            sol_index(w.start_t_s, SPIRIT.lon_west_deg) - sol_index(T0 + 1.0, SPIRIT.lon_west_deg)
            for w in relay
        ],
        minlength=10,
    )[:10]
    assert per_sol.min() >= 1 and per_sol.max() <= 4
    assert 2.0 <= per_sol.mean() <= 3.5
    minutes = np.array([w.duration_s / 60.0 for w in relay])
    peaks = np.array([w.peak_elev_deg for w in relay])
    assert minutes.max() < 15.0
    # a pass that climbs a few degrees over the mask lasts 4 min or more; a grazing one less
    assert minutes[peaks >= 12.0].min() > 4.0
    assert np.all(peaks > PLAN.relay_mask_deg) and peaks.max() <= 90.0
    assert all(w.rate_bps == PLAN.relay_rate_bps for w in relay)


def test_relay_passes_match_a_brute_search_every_second() -> None:
    sol = sol_index(T0 + 1.0, SPIRIT.lon_west_deg)
    opens, closes = (
        sol_start_t_s(sol, SPIRIT.lon_west_deg),
        sol_start_t_s(sol + 1, SPIRIT.lon_west_deg),
    )
    t = np.arange(opens - 1200.0, closes + 1200.0, 1.0)
    up = _orbiter_elev_deg(t, SPIRIT.lat_deg, SPIRIT.lon_east_deg) > PLAN.relay_mask_deg
    rises = t[1:][~up[:-1] & up[1:]]
    sets = t[:-1][up[:-1] & ~up[1:]]
    brute = [
        (r, s) for r, s in zip(rises, sets[sets > rises[0]], strict=False) if opens <= r < closes
    ]
    found = [
        w
        for w in comm_windows(SPIRIT.lat_deg, SPIRIT.lon_east_deg, PLAN, opens, closes)
        if w.kind == "relay" and opens <= w.start_t_s < closes
    ]
    assert len(found) == len(brute) >= 2
    for window, (rise, set_) in zip(found, brute, strict=True):
        assert window.start_t_s == pytest.approx(rise, abs=1.0)
        assert window.end_t_s == pytest.approx(set_, abs=1.0)
        # the refined edges sit on the mask, inside the pass
        edges = _orbiter_elev_deg(
            np.array([window.start_t_s, window.end_t_s]), SPIRIT.lat_deg, SPIRIT.lon_east_deg
        )
        assert np.all(np.abs(edges - PLAN.relay_mask_deg) < 0.05)
        assert np.all(edges > PLAN.relay_mask_deg)
        # the peak: the highest of the second-by-second samples, to a hundredth of a degree
        inside = (t >= window.start_t_s) & (t <= window.end_t_s)
        highest = _orbiter_elev_deg(t[inside], SPIRIT.lat_deg, SPIRIT.lon_east_deg).max()
        assert highest - 1e-9 <= window.peak_elev_deg < highest + 0.01


def test_windows_are_sorted_and_overlap_the_span(spirit_ten_sols: list[Window]) -> None:
    t_from, t_to = T0 + 0.3 * SOL_S, T0 + 2.6 * SOL_S
    found = comm_windows(SPIRIT.lat_deg, SPIRIT.lon_east_deg, PLAN, t_from, t_to)
    keys = [(w.start_t_s, w.kind) for w in found]
    assert keys == sorted(keys)
    assert all(w.start_t_s <= t_to and w.end_t_s >= t_from for w in found)
    # exactly the ten sols' windows that overlap the span, unclipped
    expected = [w for w in spirit_ten_sols if w.start_t_s <= t_to and w.end_t_s >= t_from]
    assert found == expected
    assert {w.kind for w in found} == {"uplink", "relay", "dte"}


def test_any_query_gives_the_same_windows(spirit_ten_sols: list[Window]) -> None:
    # sol by sol, and across each sol boundary: a window is the same whatever the query
    for k in range(10):
        t_from, t_to = T0 + k * SOL_S, T0 + (k + 1) * SOL_S
        part = comm_windows(SPIRIT.lat_deg, SPIRIT.lon_east_deg, PLAN, t_from, t_to)
        assert part == [w for w in spirit_ten_sols if w.start_t_s <= t_to and w.end_t_s >= t_from]
    again = comm_windows(SPIRIT.lat_deg, SPIRIT.lon_east_deg, PLAN, T0, T0 + 10 * SOL_S)
    assert again == spirit_ten_sols


def test_a_pass_in_progress_at_the_start_is_returned_whole(spirit_ten_sols: list[Window]) -> None:
    for window in [w for w in spirit_ten_sols if w.kind == "relay"][:6]:
        middle = 0.5 * (window.start_t_s + window.end_t_s)
        found = comm_windows(SPIRIT.lat_deg, SPIRIT.lon_east_deg, PLAN, middle, middle + 60.0)
        assert window in found  # its true start, before t_from_s
        assert found[0].start_t_s < middle


def test_a_session_lies_in_its_lmst_span_with_earth_up() -> None:
    found = comm_windows(
        OPPORTUNITY.lat_deg, OPPORTUNITY.lon_east_deg, PLAN, T_LOW_EARTH, T_LOW_EARTH + 3 * SOL_S
    )
    span_h = PLAN.uplink_minutes * 60.0 / HOUR_S_PER_LMST_H  # 60 min of Earth: 0.973 LMST h
    for kind in ("uplink", "dte"):
        sessions = [w for w in found if w.kind == kind]
        assert len(sessions) == 3  # one a sol
        for w in sessions:
            assert PLAN.uplink_lmst_h - 1e-6 <= _lmst_h(w.start_t_s, OPPORTUNITY.lon_east_deg)
            assert (
                _lmst_h(w.end_t_s, OPPORTUNITY.lon_east_deg) <= PLAN.uplink_lmst_h + span_h + 1e-6
            )
            t = np.linspace(w.start_t_s, w.end_t_s, 50)
            elev = _earth_elev_deg(t, OPPORTUNITY.lat_deg, OPPORTUNITY.lon_east_deg)
            assert np.all(elev >= PLAN.earth_min_elev_deg)
            assert w.peak_elev_deg == pytest.approx(elev.max(), abs=0.01)
            # Earth rises through 10° during it here (from -2.5° to 12°): the start is cut
            # where it crosses, the end is the session's
            assert w.duration_s < PLAN.uplink_minutes * 60.0
            start = _earth_elev_deg(w.start_t_s, OPPORTUNITY.lat_deg, OPPORTUNITY.lon_east_deg)
            assert float(start) == pytest.approx(PLAN.earth_min_elev_deg, abs=0.01)
            closes = PLAN.uplink_lmst_h + span_h
            assert _lmst_h(w.end_t_s, OPPORTUNITY.lon_east_deg) == pytest.approx(closes, abs=1e-6)
    rates = {w.kind: w.rate_bps for w in found}
    assert rates == {
        "uplink": PLAN.uplink_rate_bps,
        "dte": PLAN.dte_rate_bps,
        "relay": PLAN.relay_rate_bps,
    }


def test_a_session_with_earth_high_throughout_is_whole(spirit_ten_sols: list[Window]) -> None:
    sessions = [w for w in spirit_ten_sols if w.kind == "uplink"]
    assert len(sessions) == 10
    for w in sessions:
        assert w.duration_s == pytest.approx(PLAN.uplink_minutes * 60.0, abs=1e-6)
        assert _lmst_h(w.start_t_s, SPIRIT.lon_east_deg) == pytest.approx(
            PLAN.uplink_lmst_h, abs=1e-6
        )


def test_raising_earths_minimum_elevation_shortens_then_removes_sessions() -> None:
    t_to = T_LOW_EARTH + 3 * SOL_S
    previous: list[Window] | None = None
    totals, counts = [], []
    for min_deg in (0.0, 5.0, 10.0, 11.0, 11.9, 12.0, 20.0):
        plan = PLAN.replaced({"earth_min_elev_deg": min_deg})
        found = comm_windows(OPPORTUNITY.lat_deg, OPPORTUNITY.lon_east_deg, plan, T_LOW_EARTH, t_to)
        sessions = [w for w in found if w.kind == "uplink"]
        totals.append(sum(w.duration_s for w in sessions))
        counts.append(len(sessions))
        if previous is not None:  # each window inside one of the lower threshold's
            for w in sessions:
                assert any(p.start_t_s <= w.start_t_s and w.end_t_s <= p.end_t_s for p in previous)
        previous = sessions
    assert totals == sorted(totals, reverse=True)
    # Earth rises through 0° some ten minutes in; 11.9° it passes on two of the three sols
    assert 3 * 49 * 60.0 < totals[0] < 3 * 50 * 60.0
    assert counts == [3, 3, 3, 3, 2, 0, 0]
    assert totals[0] > totals[1] > totals[2] > totals[3] > totals[4] > 0.0
    assert totals[5] == totals[6] == 0.0  # Earth never 12° high in these sessions: none


def test_sol_boundaries_are_local_mean_midnight() -> None:
    for t in (T0, T0 + 0.4 * SOL_S, T_LOW_EARTH + 123.0):
        for mission in (SPIRIT, OPPORTUNITY):
            sol = sol_index(t, mission.lon_west_deg)
            opens = sol_start_t_s(sol, mission.lon_west_deg)
            assert opens <= t < opens + SOL_S
            lmst = float(lmst_h_from_t_s(opens + 1e-3, mission.lon_west_deg))
            assert lmst == pytest.approx(0.0, abs=1e-6)
    # the landing site's local sols are MER's sols (t_s_for_sol_lmst: sol 30 opens at T0)
    assert sol_start_t_s(
        sol_index(T0 + 10.0, SPIRIT.lon_west_deg), SPIRIT.lon_west_deg
    ) == pytest.approx(T0, abs=1e-5)


def test_window_as_json() -> None:
    w = Window("relay", 100.0, 700.0, 128_000.0, 42.0)
    assert w.as_json() == {
        "kind": "relay",
        "start_t_s": 100.0,
        "end_t_s": 700.0,
        "minutes": 10.0,
        "rate_bps": 128_000.0,
        "peak_elev_deg": 42.0,
        "capacity_mbit": 76.8,
    }


@pytest.mark.parametrize(
    ("args", "parameter"),
    [
        ((91.0, 175.0, PLAN, T0, T0 + 1.0), "lat_deg"),
        ((math.nan, 175.0, PLAN, T0, T0 + 1.0), "lat_deg"),
        ((True, 175.0, PLAN, T0, T0 + 1.0), "lat_deg"),
        ((-14.0, math.inf, PLAN, T0, T0 + 1.0), "lon_east_deg"),
        ((-14.0, "175", PLAN, T0, T0 + 1.0), "lon_east_deg"),
        ((-14.0, 175.0, {"relay_mask_deg": 10.0}, T0, T0 + 1.0), "plan"),
        ((-14.0, 175.0, PLAN, math.nan, T0), "t_from_s"),
        ((-14.0, 175.0, PLAN, T0, None), "t_to_s"),
        ((-14.0, 175.0, PLAN, T0, T0 - 1.0), "t_to_s"),
        ((-14.0, 175.0, PLAN, T0, T0 + MAX_SPAN_S + 1.0), "t_to_s"),
        ((-14.0, 175.0, PLAN, 2.0e9, 2.0e9 + 1.0), "t_from_s"),  # after DE421
    ],
)
def test_bad_arguments_are_named(args: tuple[Any, ...], parameter: str) -> None:
    with pytest.raises(InputError) as err:
        comm_windows(*args)
    assert err.value.parameter == parameter
