"""The speed of ``roverops bench rehearsal``: a campaign of one long VO drive on the embedded
Dask cluster, its warm-up apart, and what a second worker gains.

- ``rehearsal_100_runs_20m_vo_wall_s``: a campaign (``server.rehearsal.campaign.Campaign``)
  of ``runs`` runs of one ``DRIVE_STRAIGHT distance_m=20 vo=on`` (MER's 256 px VO, 0.75 m
  steps: 27 steps and 28 Navcam pairs a run) on ``RehearsalCluster.local(2)``: two worker
  processes, one thread each, Numba on one thread. Wall time from the campaign's submission
  to its last run gathered, the cluster started and warmed up before.
- ``rehearsal_warmup_s``: the cluster's start and its workers' warm-up (imports, the Numba
  kernels loaded from their cache: ``RehearsalCluster.warm_up``, with a throwaway run of a
  ``WARMUP_DRIVE_M`` VO drive unless the engine has a ``warm_up()`` of its own).
- ``dask_speedup_2_workers``: the wall time of a ``speedup_runs``-run campaign of the same
  drive on one worker over that of the same campaign (same seed: the same runs) on two.
  ``rehearsal_run_median_s``: the median of the runs' own wall times on two workers;
  ``rehearsal_run_in_process_s`` and ``rehearsal_run_in_process_cpu_s`` the wall and CPU
  time of one run in the bench's own process, before the cluster works (the CPU time is
  what a run costs when other work shares the cores).

The rover's report is a Gusev rover's after the calibration's pre-drive (``bench.rehearsal.
pairs.prepare``: Fine attitude, a short drive and a turn), its map the ground's.

The workers run at the bench's niceness (``nice``, default 0), not the server's +10: the
bench measures the engine's throughput, and on a machine shared with other work a niced
cluster measures the others' load instead (``bench.rehearsal.live`` measures the niced
cluster inside the server, beside the live rovers).
"""

from __future__ import annotations

import dataclasses
import statistics
import time
from typing import Any

import numba

from bench.rehearsal.pairs import pair_specs, prepare
from server.rehearsal.campaign import Campaign
from server.rehearsal.cluster import DEFAULT_RUN, RehearsalCluster
from sim.rehearsal.inputs import RehearsalInputs
from sim.rehearsal.run import run_once

SPEED_DRIVE_M = 20.0
SPEED_RUNS = 100
SPEEDUP_RUNS = 20
WARMUP_DRIVE_M = 1.0  # the warm-up's throwaway run: a short VO drive (every kernel loaded)
CAMPAIGN_TIMEOUT_S = 3600.0


def speed_inputs(drive_m: float = SPEED_DRIVE_M) -> RehearsalInputs:
    """The inputs of the speed campaigns: a ``vo=on`` drive of ``drive_m`` from the report
    of the first calibration pair's rover (module docstring)."""
    execution = prepare(pair_specs(1)[0])
    text = f"SEQUENCE bench_speed\nDRIVE_STRAIGHT distance_m={drive_m:g} vo=on\n"
    return dataclasses.replace(execution.inputs, sequence_text=text)


def timed_campaign(
    cluster: RehearsalCluster, inputs: RehearsalInputs, runs: int, seed: int
) -> tuple[float, list[float]]:
    """The wall time (s) of a ``runs``-run campaign from its submission to its end, and its
    runs' own wall times; ``RuntimeError`` unless every run finished."""
    start = time.perf_counter()
    campaign = Campaign(cluster, inputs, runs, seed)
    if not campaign.wait(CAMPAIGN_TIMEOUT_S):
        campaign.cancel()
        raise RuntimeError(f"a {runs}-run campaign did not end within {CAMPAIGN_TIMEOUT_S:g} s")
    wall = time.perf_counter() - start
    outcomes = campaign.outcomes()
    if campaign.state != "done" or len(outcomes) != runs:
        raise RuntimeError(
            f"the campaign ended {campaign.state} with {len(outcomes)} of {runs} runs: "
            f"{campaign.error}"
        )
    return wall, [o.wall_s for o in outcomes]


def speed_metrics(
    cluster: RehearsalCluster,
    runs: int = SPEED_RUNS,
    speedup_runs: int = SPEEDUP_RUNS,
    drive_m: float = SPEED_DRIVE_M,
    nice: int = 0,
) -> dict[str, Any]:
    """The speed figures (module docstring) on ``cluster``, a new embedded cluster of two
    workers (its start is the warm-up's), and one of one worker niced by ``nice``."""
    if cluster.slots() != 2:
        raise ValueError(f"cluster: must have 2 worker slots, has {cluster.slots()}")
    inputs = speed_inputs(drive_m)
    warm_inputs = speed_inputs(WARMUP_DRIVE_M)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)  # as a worker runs it
    try:
        run_once(warm_inputs, 0, 0)  # this process's kernels loaded
        wall, cpu = time.perf_counter(), time.process_time()
        run_once(inputs, 0, 0)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    finally:
        numba.set_num_threads(threads)
    warmup_s = cluster.warm_up(DEFAULT_RUN, warm_inputs)
    wall_s, run_walls = timed_campaign(cluster, inputs, runs, seed=1)
    wall_2_s, _ = timed_campaign(cluster, inputs, speedup_runs, seed=2)
    with RehearsalCluster.local(1, nice=nice) as single:
        single.warm_up(DEFAULT_RUN, warm_inputs)
        wall_1_s, _ = timed_campaign(single, inputs, speedup_runs, seed=2)
    return {
        "rehearsal_100_runs_20m_vo_wall_s": wall_s,
        "rehearsal_speed_runs": runs,
        "rehearsal_speed_drive_m": drive_m,
        "rehearsal_warmup_s": warmup_s,
        "rehearsal_run_median_s": statistics.median(run_walls),
        "rehearsal_throughput_s_per_run": wall_s / runs,
        "dask_speedup_2_workers": wall_1_s / wall_2_s,
        "dask_speedup_runs": speedup_runs,
        "dask_1_worker_wall_s": wall_1_s,
        "dask_2_workers_wall_s": wall_2_s,
        "rehearsal_workers_nice": nice,
        "rehearsal_run_in_process_s": wall,
        "rehearsal_run_in_process_cpu_s": cpu,
    }
