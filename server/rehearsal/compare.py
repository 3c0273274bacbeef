"""Predicted against executed: each figure the rover reported, placed in its rehearsed
distribution.

For each executed step (as the rover reported it at the step's end) and each figure:
- a number (``end_t_s``, ``imu_integration_s``, ``position_sigma_m``,
  ``hga_margin_predicted_deg``, the heading): its percentile among the runs in which the step
  ran, the share (%) of runs whose figure is below it, ties counting half; outside 95 %
  when below 2.5 or above 97.5;
- the 2-D end position (``end_est``; ``end_true`` in the truth part): its squared
  Mahalanobis distance from the risk table's Gaussian fit, outside 95 % when above the χ²
  quantile of 2 dof, 5.991 (the normalized-error test of Bar-Shalom, Li and Kirubarajan
  2001, sec. 5.4), and its percentile among the runs' own distances;
- a category (``status``, the halt's reason, ``aqf``): the share of runs that gave it,
  outside 95 % when below 5 %.

The truth part (``truth``: the true end position, maximum tilt and HGA margin) is filled
only when the caller passes the truth (the truth view); ``flags`` names only what the rover
reported.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

from server.rehearsal.risk import chi2_2dof_k2, halt_reason, mahalanobis2
from sim.rehearsal.outcome import RunOutcome, StepOutcome

OUTSIDE_LOW_PCT = 2.5
OUTSIDE_HIGH_PCT = 97.5
OUTSIDE_P = 0.05
SCALARS = ("end_t_s", "imu_integration_s", "position_sigma_m", "hga_margin_predicted_deg")


def percentile_of(x: float, values: Iterable[float]) -> float | None:
    """The share (%) of the finite ``values`` below ``x``, ties counting half; None when
    there are none or ``x`` is not finite."""
    v = np.asarray([y for y in values if math.isfinite(y)], dtype=np.float64)
    if v.size == 0 or not math.isfinite(x):
        return None
    below = int(np.count_nonzero(v < x))
    ties = int(np.count_nonzero(v == x))
    return 100.0 * (below + 0.5 * ties) / v.size


def _outside(percentile: float | None) -> bool:
    return bool(percentile is not None and not OUTSIDE_LOW_PCT <= percentile <= OUTSIDE_HIGH_PCT)


def _ordinal(pct: float) -> str:
    n = round(pct)
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


def _finite_or_none(x: Any, name: str) -> float | None:
    if x is None:
        return None
    if isinstance(x, bool) or not isinstance(x, int | float):
        raise ValueError(f"{name}: must be a number or null, got {x!r}")
    return float(x) if math.isfinite(x) else None


def _point(x: Any, name: str) -> tuple[float, float] | None:
    if x is None:
        return None
    try:
        n, e = (float(c) for c in x)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: must be [north_m, east_m] or null, got {x!r}") from exc
    return (n, e) if math.isfinite(n) and math.isfinite(e) else None


def _scalar(name: str, executed: Any, runs: Iterable[float]) -> dict[str, Any]:
    value = _finite_or_none(executed, name)
    pct = percentile_of(value, runs) if value is not None else None
    return {"name": name, "executed": value, "percentile": pct, "outside_95": _outside(pct)}


def _heading(executed: Any, runs_rad: list[float]) -> dict[str, Any]:
    """The heading, deg, placed after unwrapping everything around the runs' circular mean."""
    value = _finite_or_none(executed, "heading_est_rad")
    h = np.asarray([x for x in runs_rad if math.isfinite(x)], dtype=np.float64)
    if value is None or h.size == 0:
        shown = math.degrees(value) % 360.0 if value is not None else None
        return {
            "name": "heading_est_deg",
            "executed": shown,
            "percentile": None,
            "outside_95": False,
        }
    centre = math.atan2(float(np.sin(h).mean()), float(np.cos(h).mean()))

    def unwrap(a: Any) -> Any:
        return (a - centre + math.pi) % (2.0 * math.pi) - math.pi

    pct = percentile_of(float(unwrap(value)), unwrap(h).tolist())
    return {
        "name": "heading_est_deg",
        "executed": math.degrees(value) % 360.0,
        "percentile": pct,
        "outside_95": _outside(pct),
    }


def _pose(
    name: str, executed: Any, fit: Mapping[str, Any] | None, runs: list[tuple[float, float]]
) -> dict[str, Any]:
    point = _point(executed, {"end_est": "p_mission_est_m", "end_true": "p_mission_true_m"}[name])
    out: dict[str, Any] = {
        "name": name,
        "executed": list(point) if point else None,
        "mahalanobis2": None,
        "percentile": None,
        "outside_95": False,
    }
    if point is None or fit is None:
        return out
    mean = np.asarray(fit["mean_m"], dtype=np.float64)
    cov = np.asarray(fit["cov_m2"], dtype=np.float64)
    m2 = mahalanobis2(point, mean, cov)
    own = [mahalanobis2(p, mean, cov) for p in runs if math.isfinite(p[0]) and math.isfinite(p[1])]
    own = [min(x, 1e300) for x in own]
    out["mahalanobis2"] = m2 if math.isfinite(m2) else None
    out["percentile"] = percentile_of(min(m2, 1e300), own)
    out["outside_95"] = bool(m2 > chi2_2dof_k2(0.95))
    return out


def _category(name: str, executed: Any, shares: Mapping[str, float]) -> dict[str, Any]:
    if executed is None:
        return {"name": name, "executed": None, "probability": None, "outside_95": False}
    p = float(shares.get(str(executed), 0.0))
    return {
        "name": name,
        "executed": str(executed),
        "probability": p,
        "outside_95": bool(p < OUTSIDE_P),
    }


def _flag(line: int, fig: Mapping[str, Any]) -> str | None:
    if not fig["outside_95"]:
        return None
    name = fig["name"]
    if "probability" in fig:
        p_pct = 100.0 * fig["probability"]
        return f"line {line}: {name} {fig['executed']} had a probability of {p_pct:.1f} %"
    if "mahalanobis2" in fig:
        m2 = fig["mahalanobis2"]
        shown = f"{m2:.1f}" if m2 is not None else "unbounded: the runs did not spread"
        return f"line {line}: {name} outside the 95 % ellipse (Mahalanobis² {shown})"
    return f"line {line}: {name} at the {_ordinal(fig['percentile'])} percentile"


def _steps_of(outcomes: Sequence[RunOutcome], line: int) -> tuple[int, list[StepOutcome]]:
    """How many runs, and the steps at ``line`` that ran."""
    ran = [s for r in outcomes for s in r.steps if s.line == line and s.status != "not_run"]
    return len(outcomes), ran


def _shares(n: int, labels: Iterable[str]) -> dict[str, float]:
    counts: dict[str, int] = {}
    for label in labels:
        counts[label] = counts.get(label, 0) + 1
    return {k: v / n for k, v in counts.items()} if n else {}


def _line_number(entry: Any, where: str) -> int:
    if not isinstance(entry, Mapping):
        raise ValueError(f"{where}: must be an object, got {type(entry).__name__}")
    line = entry.get("line")
    if isinstance(line, bool) or not isinstance(line, int) or line < 1:
        raise ValueError(f"{where}.line: must be a positive integer, got {line!r}")
    return line


def _executed_figures(
    e: Mapping[str, Any],
    line: int,
    risk_line: Mapping[str, Any] | None,
    outcomes: Sequence[RunOutcome],
) -> list[dict[str, Any]]:
    n, ran = _steps_of(outcomes, line)
    all_steps = [next((s for s in r.steps if s.line == line), None) for r in outcomes]
    statuses = _shares(n, [("not_run" if s is None else s.status) for s in all_steps])
    figures = [
        _scalar(name, e.get(name), (float(getattr(s, name)) for s in ran)) for name in SCALARS
    ]
    figures.append(
        _pose(
            "end_est",
            e.get("p_mission_est_m"),
            (risk_line or {}).get("end_est"),
            [s.p_mission_est_m for s in ran],
        )
    )
    figures.append(_heading(e.get("heading_est_rad"), [s.heading_est_rad for s in ran]))
    figures.append(_category("status", e.get("status"), statuses))
    if e.get("status") == "halted":
        reasons = _shares(n, (halt_reason(s.reason) for s in ran if s.status == "halted"))
        figures.append(_category("halt_reason", halt_reason(e.get("reason")), reasons))
    figures.append(_category("aqf", e.get("aqf"), _shares(len(ran), (s.aqf for s in ran))))
    return figures


def predicted_vs_executed(
    risk: Mapping[str, Any],
    outcomes: Sequence[RunOutcome],
    executed: Sequence[Mapping[str, Any]],
    truth: Sequence[Mapping[str, Any]] | None = None,
) -> dict[str, Any]:
    """The report (module docstring) of ``executed`` (one entry per step, as reported)
    against ``risk`` (``risk_table`` of ``outcomes``); ``truth`` (per step: the true end
    position, maximum tilt and HGA margin) fills ``truth`` for the truth view only."""
    risk_lines = {entry["line"]: entry for entry in risk.get("lines", [])}
    lines: list[dict[str, Any]] = []
    flags: list[str] = []
    for k, e in enumerate(executed):
        line = _line_number(e, f"executed[{k}]")
        risk_line = risk_lines.get(line)
        figures = _executed_figures(e, line, risk_line, outcomes)
        flags.extend(f for f in (_flag(line, fig) for fig in figures) if f)
        lines.append(
            {"line": line, "command": (risk_line or {}).get("command", ""), "figures": figures}
        )
    report: dict[str, Any] = {"lines": lines, "flags": flags, "truth": None}
    if truth is not None:
        t_lines: list[dict[str, Any]] = []
        t_flags: list[str] = []
        for k, t in enumerate(truth):
            line = _line_number(t, f"truth[{k}]")
            _, ran = _steps_of(outcomes, line)
            fit = (risk_lines.get(line) or {}).get("end_true")
            figures = [
                _pose(
                    "end_true", t.get("p_mission_true_m"), fit, [s.p_mission_true_m for s in ran]
                ),
                _scalar(
                    "max_tilt_true_deg",
                    t.get("max_tilt_true_deg"),
                    (s.max_tilt_true_deg for s in ran),
                ),
                _scalar("hga_margin_deg", t.get("hga_margin_deg"), (s.hga_margin_deg for s in ran)),
            ]
            t_flags.extend(f for f in (_flag(line, fig) for fig in figures) if f)
            t_lines.append({"line": line, "figures": figures})
        report["truth"] = {"lines": t_lines, "flags": t_flags}
    return report
