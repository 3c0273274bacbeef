"""``roverops bench fusion``: both fusion filters' figures in one result (the fusion issue,
item 4): Balaram's kinematic EKF on surface eq. 22 (``bench.fusion_kinematic``) and
the radio + terrain-matching EKF's four cases (``bench.fusion_radio``), with
``filter_consistency_nees`` for each filter, and both beside SAPP in rover sessions on
Gusev and Meridiani (``bench.fusion_session``). Each part's module says how it measures.
"""

from __future__ import annotations

from typing import Any

from bench.sim import _result


def bench_fusion(
    kinematic_runs: int = 10,
    radio_seeds: int = 20,
    session_seeds: int = 6,
    session_straight_m: float = 10.0,
) -> dict[str, Any]:
    """All parts; smaller counts make a quick run (the targets stay the issue's)."""
    from bench.fusion_kinematic import bench_fusion_kinematic
    from bench.fusion_radio import bench_fusion_radio
    from bench.fusion_session import bench_fusion_session

    kinematic = bench_fusion_kinematic(n_runs=kinematic_runs)
    radio = bench_fusion_radio(n_seeds=radio_seeds)
    session = bench_fusion_session(n_seeds=session_seeds, straight_m=session_straight_m)
    metrics = {**kinematic["metrics"], **radio["metrics"], **session["metrics"]}
    metrics["filter_consistency_nees"] = {
        "kinematic_ekf": kinematic["metrics"]["kinematic_ekf_nees"],
        "radio_ekf": radio["metrics"]["radio_ekf_nees"],
    }
    return _result("fusion", metrics, {**kinematic["targets"], **radio["targets"]})
