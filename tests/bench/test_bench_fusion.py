"""``roverops bench fusion`` at its smallest: one run of each part, the output contract of
docs/DESIGN.md ("Benchmarks") and the issue's keys; figures are checked for sense, never for
speed."""

from __future__ import annotations

import math

from bench.fusion import bench_fusion

KEYS = (
    "eq22_straight_odometry_err_pct",
    "eq22_straight_ekf_err_pct",
    "eq22_turn_attitude_err_deg_max",
    "eq22_turn_attitude_err_deg_rms",
    "radio_case1_err_m",
    "radio_case2_err_m",
    "radio_case3_err_m",
    "radio_case4_err_m",
)


def test_one_run_of_each_part() -> None:
    result = bench_fusion(kinematic_runs=1, radio_seeds=1, session_seeds=1, session_straight_m=1.0)
    assert result["bench"] == "fusion" and isinstance(result["ok"], bool)
    metrics, targets = result["metrics"], result["targets"]
    for key in KEYS:
        assert math.isfinite(metrics[key]) and metrics[key] >= 0.0, key
    assert {"eq22_straight_ekf_err_pct", "radio_case4_err_m"} <= set(targets)
    nees = metrics["filter_consistency_nees"]
    assert set(nees) == {"kinematic_ekf", "radio_ekf"}
    assert all(math.isfinite(v) and v > 0.0 for v in nees.values())
    # the EKF beats averaged wheel odometry on eq. 22 (Balaram 2000: 0.3 % against 2 %)
    assert metrics["eq22_straight_ekf_err_pct"] < metrics["eq22_straight_odometry_err_pct"]
    # beside SAPP in sessions: every estimator's error on each site, in sense
    for site in ("gusev", "meridiani"):
        assert 5.0 < metrics[f"session_{site}_distance_m"] < 10.0  # 2 x 1 m, the arc, the turn
        for name in ("sapp", "kinematic_ekf", "radio_ekf"):
            err = metrics[f"session_{site}_{name}_err_m"]
            assert math.isfinite(err) and 0.0 < err < 5.0, (site, name)
