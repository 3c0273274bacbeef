"""``roverops bench sim`` at its smallest (one repeat): the output contract of docs/DESIGN.md
("Benchmarks") and issue 16's keys with their targets; figures are checked for sense (the
ratio is the quotient of the walls it names, the drive has its 21,334 cycles), never for
speed."""

from __future__ import annotations

import math

import pytest

from bench.sim import bench_sim


def test_one_repeat_gives_the_loop_figures_beside_the_worlds() -> None:
    result = bench_sim(repeats=1)
    assert result["bench"] == "sim" and isinstance(result["ok"], bool)
    metrics, targets = result["metrics"], result["targets"]
    assert metrics["session_cycles"] == 21_334  # 100 m at 3.75 cm/s, 8 Hz (Ali et al. 2005)
    for key in ("session_over_world_ratio", "session_drive_100m_wall_s", "fine_drive_hga_wall_s"):
        assert math.isfinite(metrics[key]) and metrics[key] > 0.0, key
    world_s = metrics["session_drive_100m_wall_s"] / metrics["session_over_world_ratio"]
    per_cycle_us = (metrics["session_drive_100m_wall_s"] - world_s) / 21_334 * 1e6
    assert metrics["session_cycle_us_mean"] == pytest.approx(per_cycle_us)
    assert targets["session_over_world_ratio"] == {"le": 2.0}
    assert targets["session_cycle_us_mean"] == {"le": 80.0}
    assert targets["fine_drive_hga_wall_s"] == {"le": 5.0}
