"""The one list of benchmarks: ``roverops bench NAME`` runs ``BENCHES[NAME]``.

Each entry names the function that runs it (``module:function``, imported only when that
bench runs: the server's benches need the server's dependencies, the simulator's do not)
and says in one line what it measures. Every function takes no required argument and
returns ``bench.result.bench_result``'s object; docs/BENCHMARKS.md keeps the figures.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from sim.errors import InputError


@dataclass(frozen=True)
class Bench:
    """One benchmark: its function (``module:function``) and what it measures."""

    target: str
    description: str

    def load(self) -> Callable[[], dict[str, Any]]:
        """The bench's function, its module imported now."""
        module, function = self.target.split(":")
        found: Callable[[], dict[str, Any]] = getattr(importlib.import_module(module), function)
        return found


BENCHES: dict[str, Bench] = {
    "sim": Bench(
        "bench.sim:bench_sim", "simulator speed: settling rate, a 100 m drive, an idle sol"
    ),
    "sapp": Bench(
        "bench.sapp:bench_sapp",
        "SAPP against Ali et al. 2005: attitude acquisition, odometry, HGA pointing",
    ),
    "vo": Bench(
        "bench.vo:bench_vo",
        "visual odometry against Cheng, Maimone and Matthies 2005, and an OpenCV baseline",
    ),
    "fusion": Bench(
        "bench.fusion:bench_fusion",
        "the kinematic and radio EKFs: accuracy, NEES, and beside SAPP in rover sessions",
    ),
    "faults": Bench(
        "bench.faults.report:bench_faults",
        "mobility fault protection: keep-out, sand trap, tilt, wheel drag, position 1-sigma",
    ),
    "server": Bench(
        "bench.server:bench_server",
        "the live server: a sol's wall time, WebSocket clients, validation, event-loop stalls",
    ),
    "view3d": Bench(
        "bench.view3d:bench_view3d",
        "the 3D view: draw latency to viser clients, terrain re-cuts, a sol with the view on",
    ),
    "restart": Bench(
        "bench.restart:bench_restart",
        "the server killed and restarted: lost steps, pauses, SIGTERM, restart time",
    ),
    "comm": Bench(
        "bench.comm.report:bench_comm",
        "across light time: light time, passes and data volume, gaps, kills mid-pass",
    ),
    "rehearsal": Bench(
        "bench.rehearsal:bench_rehearsal",
        "rehearsals: calibration against executions, campaign speed on Dask, live rovers beside",
    ),
    "fuzz": Bench(
        "bench.fuzz:bench_fuzz",
        "the API fuzzed from its OpenAPI (schemathesis) and the sequence-language fuzzer",
    ),
}


def run_bench(name: str) -> dict[str, Any]:
    """Run benchmark ``name``; InputError('name', ...) naming the choices.

    >>> run_bench("warp")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    sim.errors.InputError: name: unknown benchmark 'warp'; choose one of sim, sapp, vo, ...
    """
    if name not in BENCHES:
        choices = ", ".join(BENCHES)
        raise InputError("name", f"unknown benchmark {name!r}; choose one of {choices}")
    return BENCHES[name].load()()
