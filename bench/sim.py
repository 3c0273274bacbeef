"""``roverops bench sim``: speed figures of the simulator, as medians over repeats.

Output contract: ``bench.result``.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

import numpy as np

from bench.result import bench_result
from sim.loop.rover_sim import RoverSim
from sim.rover.settle import settle
from sim.world.marsclock import SOL_S
from sim.world.sites import make_terrain

_START_UTC = datetime(2004, 4, 14, 12, 0, 0, tzinfo=UTC)


def _median_wall_s(run: Callable[[], object], repeats: int) -> float:
    walls = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        walls.append(time.perf_counter() - start)
    return statistics.median(walls)


def bench_sim(repeats: int = 3) -> dict[str, Any]:
    """Settling rate, a 100 m Gusev drive and an idle sol (truth and sensors at 8 Hz)."""
    terrain = make_terrain("gusev", 1)
    rng = np.random.default_rng(0)
    n_poses = 4000
    x = rng.uniform(-40.0, 40.0, n_poses)
    y = rng.uniform(-40.0, 40.0, n_poses)
    yaw = rng.uniform(-np.pi, np.pi, n_poses)
    settle(terrain, x, y, yaw)  # builds the tiles: the rate below is settling alone
    settle_wall_s = _median_wall_s(lambda: settle(terrain, x, y, yaw), repeats)

    unsettled = []

    def drive_100m() -> None:
        sim = RoverSim("gusev", 1, _START_UTC)
        sim.drive_straight(100.0)
        unsettled.append(sim.totals.unsettled_poses)

    drive_wall_s = _median_wall_s(drive_100m, repeats)

    sims = [RoverSim("flat", seed, _START_UTC) for seed in range(5)]
    idle_walls = []
    for sim in sims:
        start = time.perf_counter()
        sim.rest(SOL_S)
        idle_walls.append(time.perf_counter() - start)

    metrics = {
        "settle_per_s": n_poses / settle_wall_s,
        "drive_100m_wall_s": drive_wall_s,
        "idle_sol_wall_s": statistics.median(idle_walls),
        # poses of the drive whose suspension did not settle (bridged; see sim.rover.drive)
        "drive_100m_unsettled_poses": max(unsettled),
        "repeats": repeats,
    }
    targets = {"drive_100m_wall_s": {"le": 5.0}, "idle_sol_wall_s": {"le": 0.5}}
    return bench_result("sim", metrics, targets)
