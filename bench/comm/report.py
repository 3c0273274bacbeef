"""``roverops bench comm``: operating across light time (issue 23), measured end to end.

Three parts, each with fixed seeds:

- ``bench.comm.light``: the simulator's one-way light time against a second computation
  from DE421 (``jplephem`` read here, ``scipy``'s ``brentq`` on the light-time equation) at
  ``LIGHT_SAMPLES`` times spread over 2004-2030: ``owlt_max_error_s`` (target 0.01 s).
- ``bench.comm.sols``: ``SOLS`` sols of Spirit in mission mode through the server's runtime
  in-process at max speed, a drive a sol, each sol's sequence sent on its own: the relay
  passes (``relay_passes_per_sol``, ``relay_pass_minutes_median``, from the windows), the
  data that reached the ground (``downlinked_mbit_per_sol``, the ground's tally of each
  pass) and ``downlinked_mbit_le_capacity`` (every pass within its window's capacity, and
  the whole within theirs); then one sol with the store far too small
  (``overflow_accounted_pct``: the store's drops that its gaps name, target 100).
- ``bench.comm.kills``: a real ``roverops serve --comm mission`` killed ``kills`` times
  (``ROVEROPS_COMM_KILLS``, default 10) during an uplink (radiated, in flight, arriving)
  and during passes (a drive in a relay pass, a status a pass brought down), restarted on
  the same database each time, against a run never killed: ``kill_mid_pass_lost`` (rows of
  the reference not stored) and ``kill_mid_pass_duplicated`` (rows stored more often than
  in the reference, or not in it), targets 0.

Over every run: ``early_arrivals``, products on the ground before their send time plus the
relay's delay plus the light time, and stored frames and events received before their
time plus the light time (target 0); ``uplink_before_window``, uplinks radiated outside an
uplink window or onboard before their light time, and sequences started before received
(target 0). Over the in-process runs: ``products_lost_with_room``, products made that are
neither on the ground, in the store, on their way nor counted as dropped, and products on
the ground that are not stored (target 0).

Output contract: ``bench.result``; ``details`` beside it: examples of what failed, the
comparison by kind of row, the kills' delays.
"""

from __future__ import annotations

import os
import time
from typing import Any

from bench.comm.kills import KILL_SPREAD, measure_kills
from bench.comm.light import SAMPLES as LIGHT_SAMPLES
from bench.comm.light import light_time_metrics
from bench.comm.sols import DRIVE_M, SOLS, measure_sols
from bench.result import bench_result
from sim.errors import InputError

KILLS = 10
KILLS_ENV = "ROVEROPS_COMM_KILLS"
MAX_KILLS = 100

TARGETS: dict[str, dict[str, float]] = {
    "owlt_max_error_s": {"le": 0.01},
    "downlinked_mbit_le_capacity": {"ge": 1},
    "early_arrivals": {"le": 0},
    "products_lost_with_room": {"le": 0},
    "overflow_accounted_pct": {"ge": 100.0},
    "uplink_before_window": {"le": 0},
    "kill_mid_pass_lost": {"le": 0},
    "kill_mid_pass_duplicated": {"le": 0},
}


def kills_from_env() -> int:
    """``ROVEROPS_COMM_KILLS``: how many times the server is killed (default ``KILLS``)."""
    text = os.environ.get(KILLS_ENV, str(KILLS))
    if not text.isdigit() or not 1 <= int(text) <= MAX_KILLS:
        raise InputError(KILLS_ENV, f"must be a whole number 1-{MAX_KILLS}, got {text!r}")
    return int(text)


def bench_comm(
    kills: int | None = None,
    sols: int = SOLS,
    light_samples: int = LIGHT_SAMPLES,
    drive_m: float = DRIVE_M,
    kill_spread: float = KILL_SPREAD,
) -> dict[str, Any]:
    """The comm bench (module docstring); smaller arguments make a quick run
    (``kill_spread``: a kill at a drive comes up to this many times the drive's wall time
    after it starts)."""
    kills = kills_from_env() if kills is None else kills
    started = time.monotonic()
    metrics: dict[str, Any] = light_time_metrics(light_samples)
    metrics.update(measure_sols(sols, drive_m))
    metrics.update(measure_kills(kills, spread=kill_spread))
    details = {k: metrics.pop(k) for k in [k for k in metrics if k.startswith("details_")]}
    parts = ("sols", "overflow", "kills")
    metrics["early_arrivals"] = sum(metrics[f"early_arrivals_{p}"] for p in parts)
    metrics["uplink_before_window"] = metrics["uplink_faults_sols"] + metrics["uplink_faults_kills"]
    metrics["products_lost_with_room"] = (
        metrics["products_lost_sols"] + metrics["products_lost_overflow"]
    )
    metrics["bench_wall_s"] = time.monotonic() - started
    return {**bench_result("comm", metrics, TARGETS), "details": details}
