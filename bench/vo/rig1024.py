"""Visual odometry on full-size Navcam pairs: the convergence drives of ``bench.vo.courses``
on Gusev, imaged at 1024 x 1024 instead of MER's 256 x 256 (Cheng, Maimone and Matthies
2005 sec. 4 ran VO on frames downsampled to 256).

The drives are ``courses``' own (``courses.drive_run`` on a ``DriveSpec`` of kind
``convergence``): a ``RoverSession`` ``vo=on`` 3 m drive at a random place and heading within
40 m of the origin, the sun 30-65 deg high, MER's 0.75 m steps, the attitude loaded Fine
from the truth, mobility fault protection relaxed; only the session's ``vo_rig`` is 1024,
so the flight VO runs with ``VoParams().for_width(1024)`` and the Navcam renders full
frames. The k-th drive here is the k-th Gusev convergence drive of ``bench_vo`` (the same
place, heading and time), imaged at the other size.

Figures: ``convergence_pct_gusev_1024``, the percentage of VO steps that converged;
``false_update_count_gusev_1024``, converged steps whose motion differs from the true motion
between their pairs by more than 5 cm or 1 deg (``courses``' scoring line); and
``vo_step_s_1024``, the median wall time of ``VisualOdometry.step`` on the converged steps
(features, stereo, tracking, RANSAC and ML on a new pair; rendering excluded), measured
inside the drives (with ``processes`` > 1 the drives share the cores, so the time is an
upper bound of a step's on an idle machine).
"""

from __future__ import annotations

import math
import statistics
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from typing import Any

from bench.vo.courses import (
    CONVERGENCE_DRIVE_M,
    DriveSpec,
    _false,
    _pct,
    drive_run,
)
from sequences import commands as cmd
from sim.errors import InputError

RIG_PX = 1024
SITE = "gusev"


def gusev_1024_specs(
    steps: int, seed: int, drive_m: float = CONVERGENCE_DRIVE_M
) -> list[DriveSpec]:
    """The drives ``drive_m`` long that make at least ``steps`` VO steps
    (``cmd.vo_step_count`` per drive)."""
    per_drive = cmd.vo_step_count(drive_m, 0.0)
    drives = math.ceil(steps / per_drive)
    return [
        DriveSpec("convergence", SITE, seed + k, k, drive_m, vo_rig=RIG_PX) for k in range(drives)
    ]


def _map(specs: list[DriveSpec], processes: int) -> list[dict[str, Any]]:
    if processes <= 1:
        return [drive_run(s) for s in specs]
    # spawn, not fork: numba's OpenMP threads may have started in this process
    with ProcessPoolExecutor(max_workers=processes, mp_context=get_context("spawn")) as pool:
        return list(pool.map(drive_run, specs))


def metrics_1024(runs: list[dict[str, Any]]) -> dict[str, float | int]:
    """The figures (module docstring) of ``courses.drive_run``'s results ``runs``."""
    steps = sum(r["steps"] for r in runs)
    converged = sum(r["vo_converged"] for r in runs)
    walls = [w for r in runs for w in r["vo_converged_walls_s"]]
    failures: Counter[str] = Counter()
    for r in runs:
        failures.update(r["failures"])
    out: dict[str, float | int] = {
        "convergence_pct_gusev_1024": _pct(converged, steps),
        "false_update_count_gusev_1024": _false([e for r in runs for e in r["vo_step_errors"]]),
        "vo_step_s_1024": statistics.median(walls) if walls else math.nan,
        "convergence_steps_gusev_1024": steps,
        "accepted_steps_gusev_1024": converged,
        "baseline_convergence_pct_gusev_1024": _pct(
            sum(r["baseline_converged"] for r in runs), steps
        ),
        "drives_gusev_1024": len(runs),
        "drives_not_completed_gusev_1024": sum(1 for r in runs if r["status"] != "completed"),
    }
    for reason, count in sorted(failures.items()):
        out[f"convergence_failures_gusev_1024_{reason.replace(' ', '_')}"] = count
    return out


def measure_gusev_1024(
    steps: int = 100, seed: int = 0, processes: int = 1, drive_m: float = CONVERGENCE_DRIVE_M
) -> dict[str, float | int]:
    """Run the Gusev convergence drives at 1024 px until at least ``steps`` VO steps, on
    ``processes`` processes, and return the figures (module docstring). ``seed`` is
    ``bench_vo``'s: the drives are its first Gusev convergence drives. ``drive_m``: their
    length (``courses``' 3 m; shorter for a quick check)."""
    for name, value in (("steps", steps), ("processes", processes)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError(name, f"must be a positive integer, got {value!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError("seed", f"must be a non-negative integer, got {seed!r}")
    if not (math.isfinite(drive_m) and 0.1 <= drive_m <= cmd.MAX_DRIVE_M):
        raise InputError("drive_m", f"must be in [0.1, {cmd.MAX_DRIVE_M:g}] m, got {drive_m!r}")
    return metrics_1024(_map(gusev_1024_specs(steps, seed, drive_m), processes))
