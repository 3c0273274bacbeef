"""What every ``roverops bench NAME --json`` prints: one JSON object, the benchmarks' contract.

::

    {"bench": NAME, "metrics": {...}, "targets": {...}, "ok": true|false, "machine": {...}}

- ``bench``: the benchmark's name in ``bench.registry``.
- ``metrics``: the figures, every one with its unit in its key (``drive_100m_wall_s``,
  ``err_pct_of_distance``); a figure that does not exist (a margin never lost) is ``null``,
  since JSON has no NaN.
- ``targets``: ``{metric: {"le": x}}`` holds when the metric is at most ``x``, ``{"ge": x}``
  when it is at least ``x`` (both may be given; NaN meets neither).
- ``ok``: every target met. ``roverops`` exits 1 when it is false, after printing, and
  names each missed target on stderr (``misses``: the metric, its value, the target).
- ``machine``: CPUs, Python and platform: wall-clock figures depend on the machine.

docs/BENCHMARKS.md keeps the latest figures under these keys, with the command and the
machine that made them. A bench may add keys beside these (``roverops bench fuzz`` adds
``details``: what to look at when a target is missed); it never renames them.
"""

from __future__ import annotations

import math
import os
import platform
from typing import Any


def meets(value: float, target: dict[str, float]) -> bool:
    """``{"le": x}``: at most x; ``{"ge": x}``: at least x (NaN meets neither).

    >>> meets(4.0, {"le": 5.0}), meets(4.0, {"ge": 5.0}), meets(float("nan"), {"le": 5.0})
    (True, False, False)
    """
    ok = True
    if "le" in target:
        ok = ok and value <= target["le"]
    if "ge" in target:
        ok = ok and value >= target["ge"]
    return bool(ok)


def json_safe(value: Any) -> Any:
    """NaN and infinities (a figure that does not exist) as ``None``, in nested dicts,
    lists and tuples too: JSON has no NaN.

    >>> json_safe({"a": float("nan"), "b": [1.0, float("inf")]})
    {'a': None, 'b': [1.0, None]}
    """
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    return value


def machine() -> dict[str, Any]:
    """This machine: CPU count, Python version, platform string."""
    return {
        "cpus": os.cpu_count(),
        "python": platform.python_version(),
        "platform": platform.platform(),
    }


def bench_result(
    name: str, metrics: dict[str, Any], targets: dict[str, dict[str, float]]
) -> dict[str, Any]:
    """The result object of bench ``name``: ``ok`` when every target is met (a target on
    a metric the bench did not measure is a KeyError: a bench's bug, not a miss).

    >>> r = bench_result("demo", {"wall_s": 0.5, "gap_m": float("nan")}, {"wall_s": {"le": 1}})
    >>> r["ok"], r["metrics"], sorted(r)
    (True, {'wall_s': 0.5, 'gap_m': None}, ['bench', 'machine', 'metrics', 'ok', 'targets'])
    """
    ok = all(meets(metrics[key], target) for key, target in targets.items())
    return {
        "bench": name,
        "metrics": json_safe(metrics),
        "targets": targets,
        "ok": ok,
        "machine": machine(),
    }


def target_text(target: dict[str, float]) -> str:
    """A target as a reader writes it.

    >>> target_text({"le": 5.0}), target_text({"ge": 1.0, "le": 2.5})
    ('≤ 5', '≥ 1 and ≤ 2.5')
    """
    bounds = [
        f"{sign} {target[key]:g}" for key, sign in (("ge", "≥"), ("le", "≤")) if key in target
    ]
    return " and ".join(bounds)


def misses(result: dict[str, Any]) -> list[dict[str, Any]]:
    """The targets ``result`` (``bench_result``'s object) missed, in its targets' order:
    ``{"metric", "value", "target"}`` each, ``value`` None for a figure that does not exist.

    >>> misses(bench_result("demo", {"wall_s": 6.0}, {"wall_s": {"le": 5}}))
    [{'metric': 'wall_s', 'value': 6.0, 'target': {'le': 5}}]
    """
    missed = []
    for metric, target in result["targets"].items():
        value = result["metrics"][metric]
        if not meets(math.nan if value is None else value, target):
            missed.append({"metric": metric, "value": value, "target": target})
    return missed
