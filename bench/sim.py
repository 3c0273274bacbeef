"""``roverops bench``: speed figures of the simulator, as medians over repeats.

Output contract (docs/DESIGN.md): ``{"bench": NAME, "metrics": {...}, "targets": {...},
"ok": bool}``, every metric with its unit in its key. A target ``{"le": x}`` holds when
the metric is at most ``x``, ``{"ge": x}`` when it is at least ``x``. Wall-clock figures
depend on the machine; the ``machine`` entry says which one ran them.
"""

from __future__ import annotations

import math
import os
import platform
import statistics
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

import numpy as np

from sim.errors import InputError
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
    return _result("sim", metrics, targets)


def _meets(value: float, target: dict[str, float]) -> bool:
    """``{"le": x}``: at most x; ``{"ge": x}``: at least x (NaN meets neither)."""
    ok = True
    if "le" in target:
        ok = ok and value <= target["le"]
    if "ge" in target:
        ok = ok and value >= target["ge"]
    return bool(ok)


def _json_safe(value: Any) -> Any:
    """NaN and infinities (a figure that does not exist, e.g. a margin never lost) as
    ``None``: JSON has no NaN."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def _result(
    name: str, metrics: dict[str, Any], targets: dict[str, dict[str, float]]
) -> dict[str, Any]:
    ok = all(_meets(metrics[key], target) for key, target in targets.items())
    return {
        "bench": name,
        "metrics": _json_safe(metrics),
        "targets": targets,
        "ok": ok,
        "machine": {
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "platform": platform.platform(),
        },
    }


def _bench_sapp() -> dict[str, Any]:
    from bench.sapp import bench_sapp  # imports this module's _result

    return bench_sapp()


def _bench_vo() -> dict[str, Any]:
    from bench.vo import bench_vo  # imports this module's _result

    return bench_vo()


def _bench_fusion() -> dict[str, Any]:
    from bench.fusion import bench_fusion  # imports this module's _result

    return bench_fusion()


BENCHES: dict[str, Callable[[], dict[str, Any]]] = {
    "sim": bench_sim,
    "sapp": _bench_sapp,
    "vo": _bench_vo,
    "fusion": _bench_fusion,
}


def run_bench(name: str) -> dict[str, Any]:
    """Run benchmark ``name``; InputError('name', ...) naming the choices."""
    if name not in BENCHES:
        raise InputError("name", f"unknown benchmark {name!r}; choose one of {', '.join(BENCHES)}")
    return BENCHES[name]()
