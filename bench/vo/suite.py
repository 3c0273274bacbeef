"""``roverops bench vo``: every figure of the visual odometry and what the ground builds
around it, in one result (issue 24's acceptance table):

- ``bench.vo.courses``: the rock course, the slope drives, convergence on both sites at MER's
  256 px, the rover's shadow, the sols 137/141 separation setting, the step times;
- ``bench.vo.rig1024``: the Gusev convergence drives imaged at 1024 x 1024;
- ``bench.vo.advised``: the Meridiani drives pointed as the ground's advisor recommends;
- ``bench.vo.sol235``: sec. 4.3's sol 235 shadow case, reproduced and prevented;
- ``bench.vo.ground_map``: the ground's terrain map against the truth.

``false_update_count`` is over every accepted step of every course (the courses', the
1024 px drives' and the advised drives'; sol 235's cases have their own figures, the
unprevented one a false update by design). Cheng, Maimone and Matthies 2005 for the method
and the cases.
"""

from __future__ import annotations

import os
from typing import Any

from bench.result import bench_result
from bench.vo.advised import meridiani_advised
from bench.vo.courses import bench_courses
from bench.vo.ground_map import ground_map_metrics
from bench.vo.rig1024 import measure_gusev_1024
from bench.vo.sol235 import bench_sol235
from sim.errors import InputError

TARGETS: dict[str, dict[str, float]] = {
    "convergence_pct_meridiani_advised": {"ge": 95.0},
    "convergence_pct_gusev_1024": {"ge": 97.0},
    "false_update_count": {"le": 0.0},
    "false_update_count_sol235": {"le": 0.0},
    "false_update_count_sol235_unprevented": {"ge": 1.0},
    "ground_map_height_err_m_p95": {"le": 0.05},
    "ground_map_sigma_coverage_pct": {"ge": 90.0, "le": 99.0},
}


def bench_vo(
    n_rock: int = 24,
    n_slope: int = 16,
    n_convergence: int = 100,
    n_shadow: int = 12,
    steps_1024: int = 100,
    n_advised: int = 100,
    n_sol235: int = 12,
    ground_map_drives: int = 3,
    seed: int = 0,
    workers: int | None = None,
) -> dict[str, Any]:
    """The whole VO bench (module docstring); the counts as in each part (``n_advised``
    Meridiani drives of 4 steps, ``ground_map_drives`` per site)."""
    counts = {"steps_1024": steps_1024, "n_advised": n_advised, "n_sol235": n_sol235,
              "ground_map_drives": ground_map_drives}  # fmt: skip
    for name, value in counts.items():
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise InputError(name, f"must be a positive integer, got {value!r}")
    courses = bench_courses(n_rock=n_rock, n_slope=n_slope, n_convergence=n_convergence,
                            n_shadow=n_shadow, seed=seed, workers=workers)  # fmt: skip
    metrics: dict[str, Any] = dict(courses["metrics"])
    metrics["false_update_count_courses"] = metrics["false_update_count"]
    # the courses time 5 poses x 5 steps on an idle machine; the 1024 px drives time every
    # converging step inside the sessions (the figure the target is on)
    metrics["vo_step_s_1024_timed_poses"] = metrics.pop("vo_step_s_1024")
    metrics.update(measure_gusev_1024(steps_1024, seed, processes=workers or (os.cpu_count() or 1)))
    metrics.update(meridiani_advised(n_advised, seed, workers))
    metrics.update(bench_sol235(n_sol235, seed, workers))
    metrics.update(ground_map_metrics(drives_per_site=ground_map_drives, seed0=seed))
    metrics["false_update_count"] = (
        metrics["false_update_count_courses"] + metrics["false_update_count_gusev_1024"]
        + metrics["false_update_count_meridiani_advised"]
    )  # fmt: skip
    return bench_result("vo", metrics, {**courses["targets"], **TARGETS})
