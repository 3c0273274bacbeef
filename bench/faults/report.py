"""``roverops bench faults``: mobility fault protection and injected faults, Monte Carlo:
the cases of ``bench.faults.cases``, each on seeds 0..RUNS-1, two processes at a time, and
their figures against the drive-safety issue's targets."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from bench.faults.cases import (
    COVERAGE_DRIVES,
    RUNS,
    coverage_run,
    drag_run,
    runs_from_env,
    sandtrap_run,
    tilt_run,
    wopmay_run,
)
from bench.faults.injected import dust_run, gyro_step_run, navcam_run
from bench.result import bench_result
from estimation.protection.limits import LIMITS
from sequences.limits import VO_STEP_MAX_M


def _map(
    pool: ProcessPoolExecutor, fn: Callable[..., dict[str, Any]], *args: Sequence[Any]
) -> list[dict[str, Any]]:
    return list(pool.map(fn, *args))


def bench_faults() -> dict[str, Any]:
    runs = runs_from_env()
    seeds = list(range(runs))
    with ProcessPoolExecutor(max_workers=2) as pool:
        wopmay_vo = _map(pool, wopmay_run, seeds, [True] * runs)
        wopmay_wheels = _map(pool, wopmay_run, seeds, [False] * runs)
        trap = _map(pool, sandtrap_run, seeds)
        tilt = _map(pool, tilt_run, seeds)
        drag_odo = _map(pool, drag_run, seeds, [False] * runs)
        drag_vo = _map(pool, drag_run, seeds, [True] * runs)
        n_cov = max(COVERAGE_DRIVES * runs // RUNS, 2)
        coverage = _map(pool, coverage_run, list(range(n_cov)))
        gyro = _map(pool, gyro_step_run, seeds)
        navcam = _map(pool, navcam_run, seeds + seeds, ["halt"] * runs + ["continue"] * runs)
        dust = _map(pool, dust_run, seeds)
    metrics = {
        "runs_per_case": runs,
        "keepout_true_entry_pct_vo": _pct(r["entered"] for r in wopmay_vo),
        "keepout_halt_pct_vo": _pct(r["halted"] for r in wopmay_vo),
        "keepout_true_entry_pct_no_vo": _pct(r["entered"] for r in wopmay_wheels),
        "keepout_halt_pct_no_vo": _pct(r["halted"] for r in wopmay_wheels),
        "sandtrap_halt_pct": _pct(r["halted"] for r in trap),
        "sandtrap_halt_distance_m": max(r["past_edge_m"] for r in trap),
        "tilt_halt_pct": _pct(r["check"] == "tilt" for r in tilt),
        "tilt_limit_exceeded_deg_max": max(r["excess_deg"] for r in tilt),
        "drag_odometry_err_pct": max(r["err_pct"] for r in drag_odo),
        "drag_vo_err_pct": max(r["err_pct"] for r in drag_vo),
        "position_sigma_coverage_pct": _pct(r["inside"] for r in coverage),
        "position_sigma_coverage_pct_vo": _pct(r["inside"] for r in coverage if r["vo"]),
        "position_sigma_coverage_pct_no_vo": _pct(r["inside"] for r in coverage if not r["vo"]),
        "coverage_drives": len(coverage),
        "gyro_step_detected_pct": _pct(r["detected"] for r in gyro),
        "gyro_step_restored_pct": _pct(r["restored"] for r in gyro),
        "gyro_step_error_at_check_deg_min": min(r["error_at_check_deg"] for r in gyro),
        "navcam_fail_clean_pct": _pct(r["clean"] for r in navcam),
        "dust_sunfind_refusal_clean_pct": _pct(r["clean"] for r in dust),
        "dust_sunfind_refused_pct": _pct(r["status"] == "failed" for r in dust),
    }
    targets = {
        "keepout_true_entry_pct_vo": {"le": 2.0},
        "sandtrap_halt_pct": {"ge": 100.0},
        "sandtrap_halt_distance_m": {"le": LIMITS.slip_check_m + VO_STEP_MAX_M},
        "tilt_limit_exceeded_deg_max": {"le": 1.0},
        "drag_vo_err_pct": {"le": 1.0},
        "position_sigma_coverage_pct": {"ge": 90.0, "le": 99.0},
        "gyro_step_detected_pct": {"ge": 100.0},
        "gyro_step_restored_pct": {"ge": 100.0},
        "navcam_fail_clean_pct": {"ge": 100.0},
        "dust_sunfind_refusal_clean_pct": {"ge": 100.0},
    }
    result = bench_result("faults", metrics, targets)
    result["details"] = {  # the seeds of the runs that missed, to look at
        "sandtrap_not_halted_seeds": [i for i, r in enumerate(trap) if not r["halted"]],
        "keepout_entered_seeds_vo": [i for i, r in enumerate(wopmay_vo) if r["entered"]],
        "drag_vo_err_pct_by_seed": [round(r["err_pct"], 3) for r in drag_vo],
        "coverage_outside_seeds": [i for i, r in enumerate(coverage) if not r["inside"]],
    }
    return result


def _pct(flags: Any) -> float:
    values = [bool(f) for f in flags]
    return 100.0 * sum(values) / len(values) if values else math.nan
