"""The rover's validation context (``server.validation.context``): sampled elevations and
the ephemeris' end (issue 13, defects 3 and 5).

Reference: the direct DE421 functions of ``sim.world.mars_frames``; the interpolated elevations
agree within 0.05 deg over a sol at both landing sites, and the direct function is called
once per sol the sequence reaches, not once per HGA pass.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

import server.validation.context as vc
from sequences.validate import MAX_EPHEMERIS_SOL, validate
from server.app import ServerConfig, create_app, data_dir_url
from server.validation.context import SampledElevation, site_context
from sim.world.ephemeris import (
    astrometric_from_mars_j2000_km,
    coverage_t_s,
    mars_velocity_j2000_km_s,
)
from sim.world.mars_frames import earth_ll_truth, elevation_rad, sun_ll_truth
from sim.world.marsclock import MISSIONS, SOL_S, sol_number_t_s, t_s_for_sol_lmst


def _site(mission: str) -> tuple[float, float]:
    m = MISSIONS[mission]
    return math.radians(m.lat_deg), math.radians(m.lon_east_deg)


def test_the_ephemeris_sol_bound_is_the_last_sol_both_missions_reach() -> None:
    """``MAX_EPHEMERIS_SOL`` (a constant: ``sequences`` may not import ``sim``) is the last
    sol that lies wholly inside DE421 for both missions, and Opportunity's is the smaller."""
    end = coverage_t_s()[1]
    last = {}
    for mission in MISSIONS:
        partial = int(sol_number_t_s(mission, end))  # the sol the ephemeris ends in
        assert (
            t_s_for_sol_lmst(mission, partial, 0.0)
            <= end
            < t_s_for_sol_lmst(mission, partial + 1, 0.0)
        )
        last[mission] = partial - 1
    assert last["opportunity"] < last["spirit"]
    assert MAX_EPHEMERIS_SOL == min(last.values()) == last["opportunity"]


@pytest.mark.parametrize("mission", ["spirit", "opportunity"])
@pytest.mark.parametrize("body", ["earth", "sun"])
def test_sampled_elevation_agrees_with_de421_over_a_sol(mission: str, body: str) -> None:
    lat, lon = _site(mission)
    direct = earth_ll_truth if body == "earth" else sun_ll_truth
    start = t_s_for_sol_lmst(mission, 42, 8.0)
    sampled = SampledElevation(body, lat, lon, start, coverage_t_s()[1])  # type: ignore[arg-type]
    t = start + np.linspace(0.0, SOL_S, 487) + 37.0  # off the quarter-sol sample grid
    truth = np.degrees(elevation_rad(direct(t, lat, lon)))
    got = np.array([sampled(float(x)) for x in t])
    assert np.max(np.abs(got - truth)) < 0.05
    assert truth.min() < -10.0 < 10.0 < truth.max()  # the sol includes rise and set
    assert sampled.blocks_sampled == 1


def test_samples_stop_at_the_ephemeris_end() -> None:
    lat, lon = _site("spirit")
    end = coverage_t_s()[1]
    sampled = SampledElevation("earth", lat, lon, end - 1000.0, end)
    truth = math.degrees(float(elevation_rad(earth_ll_truth(end - 1.0, lat, lon))))
    assert abs(sampled(end - 1.0) - truth) < 0.05
    with pytest.raises(ValueError, match="past the end"):
        sampled(end + 1.0)


@pytest.fixture
def calls(monkeypatch: pytest.MonkeyPatch) -> dict[str, int]:
    """Counts the DE421 calls of the context, by body (``mars`` for Mars' velocity)."""
    counted = {"earth": 0, "sun": 0, "mars": 0}

    def positions(body: Any, t_s: Any) -> Any:
        counted[body] += 1
        return astrometric_from_mars_j2000_km(body, t_s)

    def velocity(t_s: Any) -> Any:
        counted["mars"] += 1
        return mars_velocity_j2000_km_s(t_s)

    monkeypatch.setattr(vc, "astrometric_from_mars_j2000_km", positions)
    monkeypatch.setattr(vc, "mars_velocity", velocity)
    return counted


def test_forty_thousand_hga_passes_cost_one_ephemeris_call_per_block(
    calls: dict[str, int],
) -> None:
    """Before: one DE421 evaluation per HGA pass start and end (80,000 for this sequence,
    137 s of CPU); now one per block of 32 sols reached (10,000 h of passes: 406 sols)."""
    lat, lon = _site("spirit")
    start = t_s_for_sol_lmst("spirit", 42, 8.0)
    context = site_context("spirit", lat, lon, start, aqf="Fine")
    result = validate("HGA_PASS duration_min=15\n" * 40_000, context)
    blocks = math.ceil(40_000 * 15 * 60 / (vc.COARSE_S * vc.BLOCK))
    # Earth sets daily: over 10,000 warnings, listed up to the cap and then counted
    assert result.ok and len(result.warnings) == 1001
    summary = result.warnings[-1]
    assert summary.code == "too-many" and int(summary.message.split()[0]) > 9_000
    assert calls["earth"] <= blocks + 1 and calls["mars"] == calls["earth"]
    assert calls["sun"] == 0  # asked for nothing: sampled nothing
    assert context.sun_elevation_deg is not None
    assert -90.0 <= context.sun_elevation_deg(start + 3600.0) <= 90.0
    assert calls["sun"] == 1


def test_a_pass_on_each_of_many_sols_costs_in_proportion_to_the_reach(
    calls: dict[str, int],
) -> None:
    """The sparse case: one pass a sol for 3,000 sols samples 94 blocks, not 3,000 sols."""
    lat, lon = _site("opportunity")
    start = t_s_for_sol_lmst("opportunity", 42, 8.0)
    context = site_context("opportunity", lat, lon, start, aqf="Fine")
    text = "".join(f"@ sol {sol} 11:00 LMST HGA_PASS\n" for sol in range(43, 3043))
    result = validate(text, context)
    assert result.ok
    assert calls["earth"] <= math.ceil(3000 * SOL_S / (vc.COARSE_S * vc.BLOCK)) + 1


def test_a_step_past_the_ephemeris_is_an_error_and_prediction_stops() -> None:
    lat, lon = _site("spirit")
    end = coverage_t_s()[1]
    context = site_context("spirit", lat, lon, end - 3 * 3600.0, aqf="Fine")
    text = "HGA_PASS duration_min=15\nWAIT duration_s=10000\nHGA_PASS duration_min=15\nSUNGAZE\n"
    result = validate(text, context)
    assert [(d.line, d.code) for d in result.errors] == [(2, "beyond-ephemeris")]
    assert "past the end of the rover's ephemeris" in result.errors[0].message
    assert all(w.line < 2 for w in result.warnings)  # nothing predicted past it


def test_a_sol_tag_is_checked_against_the_rovers_own_clock() -> None:
    """Without a context the bound is the earlier mission's; with Spirit's context its
    own sols count (Spirit reaches 21 sols further)."""
    lat, lon = _site("spirit")
    context = site_context("spirit", lat, lon, t_s_for_sol_lmst("spirit", 42, 8.0))
    text = f"@ sol {MAX_EPHEMERIS_SOL + 10} 10:00 LMST HGA_PASS\n"
    assert [d.code for d in validate(text).errors] == ["beyond-ephemeris"]
    assert validate(text, context).ok
    far = validate("PLANT_SITE\n@ sol 17700 10:00 LMST HGA_PASS\n", context)
    assert [(d.line, d.column, d.code) for d in far.errors] == [(2, 1, "beyond-ephemeris")]


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    url = data_dir_url(Path(tmp_path_factory.mktemp("context")))
    app = create_app(ServerConfig(database_url=url, operator_token="context-token-1"))
    with TestClient(app) as c:
        yield c


def test_the_server_answers_an_hga_pass_past_2053_with_a_diagnostic(client: TestClient) -> None:
    """Before: 500 (DE421 raised for the pass' elevation)."""
    r = client.post(
        "/api/sequences/validate?rover=spirit",
        content="PLANT_SITE\n@ sol 17700 10:00 LMST HGA_PASS",
    )
    assert r.status_code == 200
    body = r.json()
    assert body["valid"] is False
    assert [(e["line"], e["code"]) for e in body["errors"]] == [(2, "beyond-ephemeris")]
