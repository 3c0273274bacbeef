"""The risk table: what a campaign's runs say of each line of the sequence, with a verdict.

Per step line (``risk_table``), over the runs: the probability of each status, of each halt
by reason and of entering each keep-out zone; the true and the estimated end positions as a
Gaussian fit (mean, covariance with Bessel's correction) and their 50 % and 95 % ellipses;
percentiles of heading, maximum tilt (with a histogram), IMU time, position σ, HGA margin
(true and predicted, on an HGA pass only), start and end time; the AQF's distribution.

The ellipses: a 2-D Gaussian's probability-``p`` region is the ellipse whose squared
Mahalanobis distance from the mean is below the χ² quantile with 2 degrees of freedom,
``k² = -2 ln(1 - p)`` (the χ² of 2 dof is exponential: 1.386 at 50 %, 5.991 at 95 %), with
semi-axes ``k √λ`` along the covariance's eigenvectors and the major axis's angle from
North towards East (the χ² probability region and normalized-error test of Bar-Shalom, Li
and Kirubarajan 2001, sec. 5.4).

Verdicts (``VERDICT_RULES``; percentages are of all runs):
- ``risk``: a halt (any reason) in >= 5 %, a refusal or failure in >= 5 %, entering a
  keep-out zone in >= 5 %, an HGA margin below zero in >= 5 %, or the 95th percentile of
  maximum tilt beyond the tilt limit;
- ``caution``: any of those in >= 1 % (below 5 %), the 95 % ellipse of the true end position
  touching a keep-out zone, a run's maximum tilt beyond the tilt limit, or the 95th
  percentile of tilt within ``TILT_CAUTION_MARGIN_DEG`` of it;
- ``ok`` otherwise. ``why`` lists every rule that fired, worst first.

Percentile dicts are over the runs in which the step ran (status not ``not_run``) and are
null when none did; no NaN or infinity reaches the JSON (null instead).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from estimation.protection.halt import HALT_CHECKS
from estimation.protection.keepout import KeepOutZone
from estimation.protection.limits import MobilityLimits
from sequences.language import parse_text
from sim.rehearsal.inputs import AQF_NAMES, ReportedStart
from sim.rehearsal.outcome import STATUSES, RunOutcome, StepOutcome

RISK_P = 0.05
CAUTION_P = 0.01
TILT_LIMIT_DEG = math.degrees(MobilityLimits().tilt_limit_rad)
TILT_CAUTION_MARGIN_DEG = 3.0
MAX_PATHS = 100  # runs drawn in the 3D cloud
MAX_PATH_POINTS = 200  # points per thinned path
ELLIPSE_BOUNDARY_POINTS = 72  # to test an ellipse against a keep-out zone
VERDICT_RULES = {
    "risk_p": RISK_P,
    "caution_p": CAUTION_P,
    "tilt_caution_margin_deg": TILT_CAUTION_MARGIN_DEG,
}
# words in a halt's sentence (``estimation.protection.monitor``) naming its check
_HALT_WORDS = (
    ("keep-out", "keepout"),
    ("vo failed", "vo_fail"),
    ("slip", "slip"),
    ("tilt", "tilt"),
    ("suspension", "suspension"),
    ("rocker", "suspension"),
    ("bogie", "suspension"),
    ("lmst", "lmst"),
    ("time of day", "lmst"),
    ("timeout", "timeout"),
)


def chi2_2dof_k2(p: float) -> float:
    """The χ² quantile with 2 degrees of freedom at probability ``p`` (0 <= p < 1)."""
    if not 0.0 <= p < 1.0:
        raise ValueError(f"p: must be in [0, 1), got {p!r}")
    return -2.0 * math.log1p(-p)  # the χ²(2) CDF is 1 - exp(-k²/2)


def halt_reason(reason: str | None) -> str:
    """The check a halt's reason names (``HALT_CHECKS``), ``other`` when none."""
    text = (reason or "").strip().lower()
    if text in HALT_CHECKS:
        return text
    for word, check in _HALT_WORDS:
        if word in text:
            return check
    return "other"


def _num(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


def percentiles(values: Iterable[float]) -> dict[str, float | None] | None:
    """p5, p50 and p95 of the finite ``values`` (linear interpolation), None if none."""
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=np.float64)
    if v.size == 0:
        return None
    p5, p50, p95 = np.percentile(v, [5.0, 50.0, 95.0])
    return {"p5": _num(p5), "p50": _num(p50), "p95": _num(p95)}


def gaussian_fit(points: Sequence[Sequence[float]]) -> tuple[np.ndarray, np.ndarray] | None:
    """Mean (2,) and covariance (2, 2; Bessel's correction, zero for one point) of the
    finite (North, East) ``points``, m; None if there are none."""
    p = np.asarray([q for q in points if all(math.isfinite(c) for c in q)], dtype=np.float64)
    if p.size == 0:
        return None
    p = p.reshape(-1, 2)
    mean = p.mean(axis=0)
    cov = np.cov(p, rowvar=False, ddof=1) if len(p) > 1 else np.zeros((2, 2))
    return mean, np.asarray(cov, dtype=np.float64).reshape(2, 2)


def ellipse(cov: np.ndarray, p: float) -> dict[str, float]:
    """The probability-``p`` ellipse of a 2-D Gaussian with covariance ``cov`` (m²; North,
    East): semi-axes ``a_m`` >= ``b_m`` and the major axis's angle from North towards East
    in [0, 180) deg."""
    k2 = chi2_2dof_k2(p)
    lam, vec = np.linalg.eigh(0.5 * (cov + cov.T))  # ascending eigenvalues
    lam = np.clip(lam, 0.0, None)
    major = vec[:, 1]
    angle_deg = math.degrees(math.atan2(major[1], major[0])) % 180.0
    if lam[1] - lam[0] <= 1e-12 * max(lam[1], 1e-300):
        angle_deg = 0.0  # a circle (or a point): no major axis
    return {
        "a_m": math.sqrt(k2 * lam[1]),
        "b_m": math.sqrt(k2 * lam[0]),
        "angle_deg": angle_deg if angle_deg < 180.0 else 0.0,
    }


def mahalanobis2(point: Any, mean: Any, cov: Any) -> float:
    """``(x - μ)ᵀ Σ⁻¹ (x - μ)``; with a singular Σ, the pseudo-inverse in its range and
    infinity for a point off it."""
    d = np.asarray(point, dtype=np.float64) - np.asarray(mean, dtype=np.float64)
    lam, vec = np.linalg.eigh(0.5 * (np.asarray(cov) + np.asarray(cov).T))
    tol = 1e-12 * max(float(lam.max()), 1e-30) + 1e-18
    total = 0.0
    for li, vi in zip(lam, vec.T, strict=True):
        c = float(vi @ d)
        if li > tol:
            total += c * c / li
        elif abs(c) > 1e-9:
            return math.inf
    return total


def inside_ellipse(point: Any, mean: Any, cov: Any, p: float) -> bool:
    """Whether ``point`` lies inside the probability-``p`` ellipse of the Gaussian (``mean``,
    ``cov``): its squared Mahalanobis distance is at most ``chi2_2dof_k2(p)``."""
    return mahalanobis2(point, mean, np.asarray(cov, dtype=np.float64)) <= chi2_2dof_k2(p)


def ellipse_touches(zone: KeepOutZone, mean: np.ndarray, cov: np.ndarray, p: float) -> bool:
    """Whether the probability-``p`` ellipse reaches ``zone`` (both in the same horizontal
    frame): a boundary point or the centre in the zone, or the zone's centre or a corner
    inside the ellipse."""
    k = math.sqrt(chi2_2dof_k2(p))
    lam, vec = np.linalg.eigh(0.5 * (cov + cov.T))
    radii = k * np.sqrt(np.clip(lam, 0.0, None))
    t = np.linspace(0.0, 2.0 * math.pi, ELLIPSE_BOUNDARY_POINTS, endpoint=False)
    boundary = mean + (vec @ (radii[:, None] * np.vstack([np.cos(t), np.sin(t)]))).T
    for q in (mean, *boundary):
        if zone.clearance_m((float(q[0]), float(q[1]))) <= 0.0:
            return True
    inner = zone.vertices_s or (zone.centre_s,)
    return any(inside_ellipse(v, mean, cov, p) for v in inner)


def zones_in_mission(start: ReportedStart) -> tuple[KeepOutZone, ...]:
    """The reported keep-out zones of the current Site moved into the mission frame (by the
    Site origin the estimate implies); zones of other Sites are left out."""
    dn, de = start.site_origin_mission_m
    moved = []
    for z in start.keepout_zones:
        if z.site_index != start.site_index:
            continue
        if z.vertices_s:
            moved.append(
                KeepOutZone.polygon(z.name, -1, [(x + dn, y + de) for x, y in z.vertices_s])
            )
        else:
            cx, cy = z.centre_s
            moved.append(KeepOutZone.circle(z.name, -1, cx + dn, cy + de, z.radius_m))
    return tuple(moved)


def _pose(points: list[tuple[float, float]]) -> dict[str, Any] | None:
    fit = gaussian_fit(points)
    if fit is None:
        return None
    mean, cov = fit
    return {
        "mean_m": [float(mean[0]), float(mean[1])],
        "cov_m2": [[float(cov[0, 0]), float(cov[0, 1])], [float(cov[1, 0]), float(cov[1, 1])]],
        "ellipse_50": ellipse(cov, 0.5),
        "ellipse_95": ellipse(cov, 0.95),
    }


def _heading_percentiles(headings_rad: list[float]) -> dict[str, float | None] | None:
    """Percentiles of headings unwrapped around their circular mean (so p5 <= p50 <= p95),
    shifted by whole turns to put p50 in [0, 360) deg."""
    h = np.asarray([x for x in headings_rad if math.isfinite(x)], dtype=np.float64)
    if h.size == 0:
        return None
    centre = math.atan2(float(np.sin(h).mean()), float(np.cos(h).mean()))
    unwrapped = centre + (h - centre + math.pi) % (2.0 * math.pi) - math.pi
    pct = np.degrees(np.percentile(unwrapped, [5.0, 50.0, 95.0]))
    shift = 360.0 * math.floor(pct[1] / 360.0)
    return {"p5": _num(pct[0] - shift), "p50": _num(pct[1] - shift), "p95": _num(pct[2] - shift)}


def _tilt(values: list[float]) -> dict[str, Any] | None:
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=np.float64)
    if v.size == 0:
        return None
    top = float(v.max())
    width = next(w for w in (0.25, 0.5, 1.0, 2.0, 5.0, 10.0, 30.0) if top / w <= 20.0)
    edges = np.arange(0.0, math.floor(top / width) * width + 1.5 * width, width)
    counts, _ = np.histogram(np.clip(v, 0.0, None), bins=edges)
    out: dict[str, Any] = dict(percentiles(v.tolist()) or {})
    out["max"] = top
    out["hist"] = {"edges_deg": [float(e) for e in edges], "counts": [int(c) for c in counts]}
    return out


def _pct(p: float) -> str:
    x = 100.0 * p
    return f"{x:.0f} %" if x >= 10.0 or x == round(x) else f"{x:.1f} %"


def _verdict(
    line: dict[str, Any],
    tilt_limit_deg: float,
    hga_negative_p: float,
    zones_touched: list[str],
) -> tuple[str, list[str]]:
    risk: list[str] = []
    caution: list[str] = []

    def grade(p: float, text: str) -> None:
        if p >= RISK_P:
            risk.append(text)
        elif p >= CAUTION_P:
            caution.append(text)

    halted = line["status"]["halted"]
    if halted > 0.0:
        reasons = ", ".join(
            f"{k} {_pct(v)}" for k, v in sorted(line["halts"].items(), key=lambda kv: -kv[1])
        )
        grade(halted, f"halt {_pct(halted)} ({reasons})")
    for status in ("refused", "failed"):
        grade(line["status"][status], f"{status} {_pct(line['status'][status])}")
    for zone, p in line["keepouts"].items():
        grade(p, f"enters keep-out {zone} {_pct(p)}")
    grade(hga_negative_p, f"HGA margin below 0 in {_pct(hga_negative_p)}")
    tilt = line["max_tilt_deg"]
    if tilt is not None and tilt["p95"] is not None:
        if tilt["p95"] > tilt_limit_deg:
            risk.append(f"tilt p95 {tilt['p95']:.1f} deg > limit {tilt_limit_deg:.1f} deg")
        elif tilt["max"] > tilt_limit_deg:
            caution.append(f"tilt max {tilt['max']:.1f} deg > limit {tilt_limit_deg:.1f} deg")
        elif tilt["p95"] > tilt_limit_deg - TILT_CAUTION_MARGIN_DEG:
            caution.append(f"tilt p95 {tilt['p95']:.1f} deg near limit {tilt_limit_deg:.1f} deg")
    caution.extend(f"95 % ellipse reaches keep-out {z}" for z in zones_touched)
    verdict = "risk" if risk else "caution" if caution else "ok"
    return verdict, risk + caution


def _step_lines(sequence_text: str, outcomes: Sequence[RunOutcome]) -> list[tuple[int, str]]:
    """(line, command) of each step: the parsed sequence's, and any line a run reported."""
    commands: dict[int, str] = {}
    for step in parse_text(sequence_text).sequence.steps:
        commands[step.line] = step.command.describe()
    for run in outcomes:
        for s in run.steps:
            commands.setdefault(s.line, s.command)
    return sorted(commands.items())


def _thinned(path: list[tuple[float, float]]) -> list[list[float]]:
    finite = [p for p in path if math.isfinite(p[0]) and math.isfinite(p[1])]
    if len(finite) > MAX_PATH_POINTS:
        idx = np.linspace(0, len(finite) - 1, MAX_PATH_POINTS).round().astype(int)
        finite = [finite[i] for i in idx]
    return [[round(n, 3), round(e, 3)] for n, e in finite]


def _line_entry(
    line: int,
    command: str,
    steps: list[StepOutcome | None],
    zones: Sequence[KeepOutZone],
    tilt_limit_deg: float,
) -> dict[str, Any]:
    n = len(steps)
    ran = [s for s in steps if s is not None and s.status != "not_run"]
    status_counts = dict.fromkeys(STATUSES, 0)
    halts: dict[str, int] = {}
    keepouts: dict[str, int] = {z.name: 0 for z in zones}
    for s in steps:
        status_counts["not_run" if s is None else s.status] += 1
        if s is None:
            continue
        if s.status == "halted":
            reason = halt_reason(s.reason)
            halts[reason] = halts.get(reason, 0) + 1
        for z in set(s.keepouts_entered):
            keepouts[z] = keepouts.get(z, 0) + 1
    share = (lambda k: k / n) if n else (lambda k: 0.0)
    aqf_counts = {a: sum(1 for s in ran if s.aqf == a) for a in (*AQF_NAMES, *{s.aqf for s in ran})}
    hga = [s.hga_margin_deg for s in ran if math.isfinite(s.hga_margin_deg)]
    entry: dict[str, Any] = {
        "line": line,
        "command": command,
        "verdict": "ok",
        "why": [],
        "status": {k: share(v) for k, v in status_counts.items()},
        "halts": {k: share(v) for k, v in sorted(halts.items())},
        "keepouts": {k: share(v) for k, v in sorted(keepouts.items())},
        "end_true": _pose([s.p_mission_true_m for s in ran]),
        "end_est": _pose([s.p_mission_est_m for s in ran]),
        "heading_true_deg": _heading_percentiles([s.heading_true_rad for s in ran]),
        "max_tilt_deg": _tilt([s.max_tilt_true_deg for s in ran]),
        "aqf": {a: c / len(ran) for a, c in aqf_counts.items() if c} if ran else {},
        "imu_integration_s": percentiles(s.imu_integration_s for s in ran),
        "position_sigma_m": percentiles(s.position_sigma_m for s in ran),
        "hga_margin_deg": percentiles(hga),
        "hga_margin_predicted_deg": percentiles(s.hga_margin_predicted_deg for s in ran),
        "start_t_s": percentiles(s.start_t_s for s in ran),
        "end_t_s": percentiles(s.end_t_s for s in ran),
    }
    touched: list[str] = []
    fit = gaussian_fit([s.p_mission_true_m for s in ran])
    if fit is not None:
        touched = [z.name for z in zones if ellipse_touches(z, fit[0], fit[1], 0.95)]
    hga_negative_p = share(sum(1 for m in hga if m < 0.0))
    entry["verdict"], entry["why"] = _verdict(entry, tilt_limit_deg, hga_negative_p, touched)
    return entry


def risk_table(
    sequence_text: str,
    outcomes: Sequence[RunOutcome],
    *,
    keepout_zones_mission: Sequence[KeepOutZone] = (),
    tilt_limit_deg: float = TILT_LIMIT_DEG,
) -> dict[str, Any]:
    """The risk table of ``outcomes`` (the runs of a campaign of ``sequence_text``), in the
    shape of the module docstring; JSON-ready, no NaN. ``keepout_zones_mission``: the zones
    in the mission frame (``zones_in_mission``) for the ellipses' test and to list at 0 %;
    ``tilt_limit_deg``: the rover's tilt limit (its parameters)."""
    if not math.isfinite(tilt_limit_deg) or tilt_limit_deg <= 0.0:
        raise ValueError(f"tilt_limit_deg: must be positive, got {tilt_limit_deg!r}")
    runs = sorted(outcomes, key=lambda r: r.run_index)
    by_line = [{s.line: s for s in r.steps} for r in runs]
    lines = [
        _line_entry(
            line, command, [m.get(line) for m in by_line], keepout_zones_mission, tilt_limit_deg
        )
        for line, command in _step_lines(sequence_text, runs)
    ]
    ends = []
    for r in runs:
        ran = [s.end_t_s for s in r.steps if s.status != "not_run" and math.isfinite(s.end_t_s)]
        if ran:
            ends.append(max(ran))
    paths = []
    for r in runs[:MAX_PATHS]:
        path = [p for s in r.steps for p in s.path_true_m]
        paths.append(_thinned(path))
    return {"runs": len(runs), "lines": lines, "end_t_s": percentiles(ends), "paths": paths}
