"""``roverops bench fusion``: both fusion filters' figures in one result (the fusion issue,
item 4): Balaram's kinematic EKF on surface eq. 22 (``bench.fusion_kinematic``) and
the radio + terrain-matching EKF's four cases (``bench.fusion_radio``), with
``filter_consistency_nees`` for each filter, and both beside SAPP in rover sessions on
Gusev and Meridiani (here). Each part says how it measures.

The sessions: what an operator comparing estimators sees (the fusion issue, item 3),
measured. Each seed is a ``RoverSession`` with ``estimators=("sapp", "kinematic_ekf",
"radio_ekf")`` on a real site's terrain with slip, at 10:00 LMST of its mission's sol
100 + seed (so the relay orbiter's passes fall differently while the sun stays where it
is): GetFineAttitude, then a course (``course``: 10 m straight, a 90° turn in place, a 60°
arc of 5 m radius, 10 m straight: ~25 m). Each estimator's final mission-frame position
error is taken against the truth at the end of the course.

Session figures, per site, RMS over seeds: ``session_<site>_<estimator>_err_m`` and the
same as a percentage of the distance driven, ``..._err_pct``. There are no targets: Ali et
al. 2005's requirement for SAPP (10 % of the distance) is ``roverops bench sapp``'s, and
the papers give no figure for these courses.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from bench.result import bench_result
from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.session import RoverSession
from sim.world.marsclock import t_s_for_sol_lmst, t_s_to_utc
from sim.world.sites import site as site_named

SITES = ("gusev", "meridiani")
ESTIMATORS = ("sapp", "kinematic_ekf", "radio_ekf")
FIRST_SOL, LMST_H = 100, 10.0  # mid-morning: Sunfind and Sungaze have the sun


def course(straight_m: float) -> tuple[cmd.Command, ...]:
    """The course: two straight legs of ``straight_m`` around a turn in place and an arc."""
    return (
        cmd.DriveStraight(distance_m=straight_m),
        cmd.TurnInPlace(angle_deg=90.0),
        cmd.DriveArc(radius_m=5.0, angle_deg=60.0),
        cmd.DriveStraight(distance_m=straight_m),
    )


def run_session_seed(site: str, seed: int, straight_m: float = 10.0) -> dict[str, float]:
    """One course: each estimator's final position error (m) and the distance driven (m)."""
    mission = site_named(site).mission
    start = t_s_to_utc(t_s_for_sol_lmst(mission, FIRST_SOL + seed, LMST_H))
    session = RoverSession(site, seed, start, estimators=ESTIMATORS, frame_every_s=10.0)
    reports = session.run([cmd.GetFineAttitude(), *course(straight_m)])
    failed = [r.command for r in reports if r.status != "completed"]
    if failed:
        raise RuntimeError(f"{site} seed {seed}: {failed} did not complete")
    last = session.truths[-1]  # the scores of the last frame
    out = {"sapp": last.position_error_m, "distance_m": session.sim.totals.distance_truth_m}
    for name, e in last.estimators.items():
        out[name] = float(e["position_error_m"])
    return out


def bench_fusion_session(
    n_seeds: int = 6, straight_m: float = 10.0, workers: int | None = None
) -> dict[str, Any]:
    """The session figures (module docstring) as ``bench.result``'s object (shorter
    straight legs make a quick run)."""
    if isinstance(n_seeds, bool) or not isinstance(n_seeds, int) or not 1 <= n_seeds <= 100:
        raise InputError("n_seeds", f"must be an integer in [1, 100], got {n_seeds!r}")
    if not (math.isfinite(straight_m) and 0.5 <= straight_m <= 100.0):
        raise InputError("straight_m", f"must be in [0.5, 100] m, got {straight_m!r}")
    args = [(site, seed, straight_m) for site in SITES for seed in range(n_seeds)]
    n_workers = workers if workers is not None else (os.cpu_count() or 1)
    if n_workers <= 1:
        runs = [run_session_seed(*a) for a in args]
    else:
        with ProcessPoolExecutor(max_workers=min(n_workers, len(args))) as pool:
            runs = list(pool.map(run_session_seed, *zip(*args, strict=True)))
    metrics: dict[str, Any] = {"session_n_seeds": n_seeds}
    for site in SITES:
        mine = [r for (s, _, _), r in zip(args, runs, strict=True) if s == site]
        distance = float(np.mean([r["distance_m"] for r in mine]))
        metrics[f"session_{site}_distance_m"] = distance
        for name in ESTIMATORS:
            rms = math.sqrt(float(np.mean([r[name] ** 2 for r in mine])))
            metrics[f"session_{site}_{name}_err_m"] = rms
            metrics[f"session_{site}_{name}_err_pct"] = 100.0 * rms / distance
    return bench_result("fusion_session", metrics, {})


def bench_fusion(
    kinematic_runs: int = 10,
    radio_seeds: int = 20,
    session_seeds: int = 6,
    session_straight_m: float = 10.0,
) -> dict[str, Any]:
    """All parts; smaller counts make a quick run (the targets stay the issue's)."""
    from bench.fusion_kinematic import bench_fusion_kinematic
    from bench.fusion_radio import bench_fusion_radio

    kinematic = bench_fusion_kinematic(n_runs=kinematic_runs)
    radio = bench_fusion_radio(n_seeds=radio_seeds)
    session = bench_fusion_session(n_seeds=session_seeds, straight_m=session_straight_m)
    metrics = {**kinematic["metrics"], **radio["metrics"], **session["metrics"]}
    metrics["filter_consistency_nees"] = {
        "kinematic_ekf": kinematic["metrics"]["kinematic_ekf_nees"],
        "radio_ekf": radio["metrics"]["radio_ekf_nees"],
    }
    return bench_result("fusion", metrics, {**kinematic["targets"], **radio["targets"]})
