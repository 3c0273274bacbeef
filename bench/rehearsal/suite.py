"""``roverops bench rehearsal``: a rehearsal's calibration against executions, its speed on
Dask, and the live rovers beside a campaign (issue 25's acceptance).

- Calibration (``bench.rehearsal.pairs``): ``pairs`` (rehearsal, execution) pairs, each a
  campaign of ``runs_per_pair`` runs from what the ground knows of a real session, then
  that session's execution. ``rehearsal_coverage_95_pct``: the share of pairs whose
  executed true end lies inside the rehearsal's 95 % ellipse (a perfectly calibrated
  rehearsal: 95 %; target 90-99), ``rehearsal_coverage_50_pct`` inside its 50 % ellipse
  (target 38-62). ``rehearsal_pairs`` counts the pairs scored (target at least 100: with
  100 pairs a calibrated rehearsal meets both ranges about 99 % of the time, with 40 about
  80 %); ``rehearsal_mahalanobis2_median`` the median squared distance (chi-square with 2
  degrees of freedom: 1.39 when calibrated). The campaigns run on the bench's embedded
  cluster while the main process runs the executions.
- Speed (``bench.rehearsal.speed``): ``rehearsal_100_runs_20m_vo_wall_s`` (target at most
  120 s), ``rehearsal_warmup_s`` apart, ``dask_speedup_2_workers`` (target at least 1.7).
- Live rovers (``bench.rehearsal.live``): ``ws_p99_during_campaign_ms`` (target at most
  100 ms).

Every size is a parameter; the defaults are the issue's, smaller ones make the quick run of
``tests/bench/test_bench_rehearsal.py`` (the targets stay the issue's). ``details`` holds
each pair's figures (beside the contract's keys, ``bench.result``).
"""

from __future__ import annotations

import math
import statistics
import time
from typing import Any

from bench.rehearsal.live import live_metrics
from bench.rehearsal.pairs import (
    RUNS_PER_PAIR,
    SEQUENCE_M,
    Execution,
    coverage,
    pair_specs,
    prepare,
)
from bench.rehearsal.speed import SPEED_DRIVE_M, SPEED_RUNS, SPEEDUP_RUNS, speed_metrics
from bench.result import bench_result
from server.rehearsal.campaign import Campaign
from server.rehearsal.cluster import RehearsalCluster

PAIRS = 100
TARGETS: dict[str, dict[str, float]] = {
    "rehearsal_pairs": {"ge": 100},
    "rehearsal_coverage_95_pct": {"ge": 90.0, "le": 99.0},
    "rehearsal_coverage_50_pct": {"ge": 38.0, "le": 62.0},
    "rehearsal_100_runs_20m_vo_wall_s": {"le": 120.0},
    "dask_speedup_2_workers": {"ge": 1.7},
    "ws_p99_during_campaign_ms": {"le": 100.0},
}
CALIBRATION_TIMEOUT_S = 6 * 3600.0


def calibration_metrics(
    cluster: RehearsalCluster,
    pairs: int = PAIRS,
    runs_per_pair: int = RUNS_PER_PAIR,
    lengths_m: tuple[float, float] = SEQUENCE_M,
) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """The calibration figures and each pair's (module docstring), on ``cluster``."""
    started = time.perf_counter()
    rows: list[dict[str, Any]] = []
    running: list[tuple[Execution, Campaign]] = []
    for spec in pair_specs(pairs, lengths_m):
        execution = prepare(spec)  # the ground's inputs fixed before anything runs
        campaign = Campaign(cluster, execution.inputs, runs_per_pair, seed=spec.index)
        execution.run()  # the execution, while the workers rehearse
        running.append((execution, campaign))
    deadline = time.monotonic() + CALIBRATION_TIMEOUT_S
    for execution, campaign in running:
        if not campaign.wait(max(1.0, deadline - time.monotonic())):
            raise RuntimeError(f"pair {execution.spec.index}: its campaign did not end")
        if campaign.state != "done":
            raise RuntimeError(
                f"pair {execution.spec.index}: campaign {campaign.state}: {campaign.error}"
            )
        assert execution.true_end_ne is not None
        spec = execution.spec
        rows.append(
            {
                "pair": spec.index, "site": spec.site_name, "kind": spec.kind,
                "length_m": spec.length_m, "vo": spec.vo,
                "sequence": execution.inputs.sequence_text.splitlines()[1],
                "position_sigma_m": execution.inputs.start.position_sigma_m,
                "executed": execution.statuses,
                "run_statuses": sorted(
                    {o.steps[-1].status for o in campaign.outcomes()}
                ),
                **coverage(campaign.outcomes(), execution.true_end_ne),
            }
        )  # fmt: skip
    scored = [r for r in rows if r["fitted"]]
    n = len(scored)

    def pct(key: str) -> float:
        return 100.0 * sum(r[key] for r in scored) / n if n else math.nan

    m2 = [r["mahalanobis2"] for r in scored]
    metrics = {
        "rehearsal_pairs": n,
        "rehearsal_runs_per_pair": runs_per_pair,
        "rehearsal_coverage_95_pct": pct("in_95"),
        "rehearsal_coverage_50_pct": pct("in_50"),
        "rehearsal_mahalanobis2_median": statistics.median(m2) if m2 else math.nan,
        "rehearsal_miss_median_m": statistics.median(r["miss_m"] for r in scored)
        if n
        else math.nan,
        "rehearsal_calibration_wall_s": time.perf_counter() - started,
    }
    for label, keep in (("vo", True), ("no_vo", False)):
        part = [r for r in scored if r["vo"] is keep]
        metrics[f"rehearsal_coverage_95_{label}_pct"] = (
            100.0 * sum(r["in_95"] for r in part) / len(part) if part else math.nan
        )
    return metrics, rows


def bench_rehearsal(
    pairs: int = PAIRS,
    runs_per_pair: int = RUNS_PER_PAIR,
    lengths_m: tuple[float, float] = SEQUENCE_M,
    speed_runs: int = SPEED_RUNS,
    speedup_runs: int = SPEEDUP_RUNS,
    speed_drive_m: float = SPEED_DRIVE_M,
    live_runs: int = 40,
    ws_clients: int = 50,
    ws_window_s: float = 10.0,
) -> dict[str, Any]:
    """The rehearsal bench (module docstring); the defaults are the issue's sizes."""
    started = time.perf_counter()
    metrics: dict[str, Any] = {}
    with RehearsalCluster.local(2, nice=0) as cluster:
        metrics.update(speed_metrics(cluster, speed_runs, speedup_runs, speed_drive_m))
        calibration, rows = calibration_metrics(cluster, pairs, runs_per_pair, lengths_m)
    metrics.update(calibration)
    metrics.update(live_metrics(live_runs, speed_drive_m, ws_clients, ws_window_s))
    metrics["bench_wall_s"] = time.perf_counter() - started
    result = bench_result("rehearsal", metrics, TARGETS)
    result["details"] = {"pairs": rows}
    return result
