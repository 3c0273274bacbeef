"""``roverops bench rehearsal`` in a quick version: the same pieces on a small scale (2
calibration pairs of 3 runs, campaigns of a 2 m VO drive, 3 WebSocket clients for 2 s
beside a campaign inside the server), checking the output contract (``bench.result``) and
that the figures make sense. No speed is asserted (TESTING.md: benchmarks measure, tests
assert correctness)."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

from bench.registry import BENCHES
from bench.rehearsal.pairs import coverage, pair_specs
from bench.rehearsal.suite import TARGETS, bench_rehearsal
from sim.rehearsal.outcome import RunOutcome, StepOutcome


@pytest.fixture(scope="module")
def quick() -> dict[str, Any]:
    return bench_rehearsal(
        pairs=2, runs_per_pair=3, lengths_m=(2.0, 2.5), speed_runs=2, speedup_runs=2,
        speed_drive_m=2.0, live_runs=8, ws_clients=3, ws_window_s=2.0,
    )  # fmt: skip


def test_registered() -> None:
    assert BENCHES["rehearsal"].target == "bench.rehearsal:bench_rehearsal"


def test_the_output_contract(quick: dict[str, Any]) -> None:
    assert json.loads(json.dumps(quick, allow_nan=False)) == quick  # plain JSON
    assert set(quick) == {"bench", "metrics", "targets", "ok", "machine", "details"}
    assert quick["bench"] == "rehearsal"
    assert quick["targets"] == TARGETS
    assert set(TARGETS) <= set(quick["metrics"])
    assert quick["ok"] is False  # 2 pairs are not the 100 of the target
    for key, value in quick["metrics"].items():
        assert isinstance(value, (int, float)) and not isinstance(value, bool), key


def test_the_figures_make_sense(quick: dict[str, Any]) -> None:
    m = quick["metrics"]
    assert m["rehearsal_pairs"] == 2 and m["rehearsal_runs_per_pair"] == 3
    for key in ("rehearsal_coverage_95_pct", "rehearsal_coverage_50_pct"):
        assert m[key] in (0.0, 50.0, 100.0), key  # a share of 2 pairs
    assert m["rehearsal_coverage_95_pct"] >= m["rehearsal_coverage_50_pct"]  # nested ellipses
    assert m["rehearsal_speed_runs"] == 2 and m["dask_speedup_runs"] == 2
    assert 0.0 < m["rehearsal_run_median_s"] < m["rehearsal_100_runs_20m_vo_wall_s"] * 2
    assert m["dask_speedup_2_workers"] > 0.0
    assert m["rehearsal_warmup_s"] > 0.0
    assert m["ws_clients_during_campaign"] >= 1
    assert m["ws_p99_during_campaign_ms"] >= m["ws_p50_during_campaign_ms"] > 0.0
    pairs = quick["details"]["pairs"]
    assert [p["site"] for p in pairs] == ["gusev", "meridiani"]
    assert [p["vo"] for p in pairs] == [True, False]
    for p in pairs:
        assert p["runs"] == 3 and p["executed"]
        assert p["in_95"] == (p["mahalanobis2"] <= -2.0 * math.log(0.05))
        assert p["in_50"] == (p["mahalanobis2"] <= -2.0 * math.log(0.5))


def test_pairs_vary() -> None:
    specs = pair_specs(8)
    assert {s.site_name for s in specs} == {"gusev", "meridiani"}
    assert {s.vo for s in specs} == {True, False}
    assert {s.kind for s in specs} == {"straight", "arc"}
    assert len({s.seed for s in specs}) == 8
    assert all(2.0 <= s.length_m <= 6.0 for s in specs)
    with pytest.raises(ValueError, match="pairs"):
        pair_specs(0)


def _run(index: int, end: tuple[float, float]) -> RunOutcome:
    step = StepOutcome(
        line=2, command="DRIVE_STRAIGHT distance_m=2", status="completed", reason=None,
        start_t_s=0.0, end_t_s=60.0, p_mission_true_m=end, p_mission_est_m=end,
        heading_true_rad=0.0, heading_est_rad=0.0, max_tilt_true_deg=1.0, aqf="Fine",
        imu_integration_s=60.0, position_sigma_m=0.1,
    )  # fmt: skip
    return RunOutcome(run_index=index, seed=0, steps=(step,))


def test_coverage_against_an_independent_gaussian() -> None:
    # runs drawn from N(0, diag(1, 4)): the ellipse tests agree with the chi-square radii
    rng = np.random.default_rng(3)
    ends = rng.normal(0.0, 1.0, (4000, 2)) * np.array([1.0, 2.0])
    runs = [_run(k, (float(n), float(e))) for k, (n, e) in enumerate(ends)]
    inside_95 = coverage(runs, (0.0, 2.0 * 2.3))  # m2 = 2.3^2 = 5.29 < 5.99
    outside_95 = coverage(runs, (2.6, 0.0))  # m2 = 6.76 > 5.99
    inside_50 = coverage(runs, (1.1, 0.0))  # m2 = 1.21 < 1.386
    assert inside_95["in_95"] and not inside_95["in_50"]
    assert not outside_95["in_95"]
    assert inside_50["in_50"] and inside_50["in_95"]
    assert inside_50["mahalanobis2"] == pytest.approx(1.21, rel=0.05)
    assert coverage([], (0.0, 0.0))["fitted"] is False
