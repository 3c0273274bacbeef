"""Predicted against executed (server.rehearsal.compare) on hand-made runs: percentiles with
ties counting half, the 2-D pose against χ²(2), categories, the flags, the truth part only
when the truth is given, and bad input refused."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.stats import chi2

from server.rehearsal.compare import percentile_of, predicted_vs_executed
from server.rehearsal.risk import risk_table
from sim.rehearsal.outcome import RunOutcome, StepOutcome

SEQUENCE = "SEQUENCE c\nDRIVE_STRAIGHT distance_m=3.0\n"
N = 40


def _outcomes() -> list[RunOutcome]:
    rng = np.random.default_rng(5)
    ends = rng.multivariate_normal([3.0, 0.5], [[0.04, 0.0], [0.0, 0.01]], size=N)
    runs = []
    for i in range(N):
        halted = i < 4  # 10 %
        step = StepOutcome(
            line=2,
            command="DRIVE_STRAIGHT distance_m=3.0",
            status="halted" if halted else "completed",
            reason="slip check: slip 45.0 % over 1.00 m" if halted else None,
            start_t_s=0.0,
            end_t_s=100.0 + i,  # 100 .. 139
            p_mission_true_m=(float(ends[i, 0]), float(ends[i, 1])),
            p_mission_est_m=(float(ends[i, 0]) + 0.1, float(ends[i, 1])),
            heading_true_rad=0.01 * i,
            heading_est_rad=0.01 * i,
            max_tilt_true_deg=float(i % 10),
            aqf="Fine",
            imu_integration_s=50.0 + (i % 4),  # 10 each of 50, 51, 52, 53
            position_sigma_m=0.2,
        )
        runs.append(RunOutcome(i, 0, (step,)))
    return runs


def _figures(report: dict[str, object], line: int = 0) -> dict[str, dict[str, object]]:
    return {f["name"]: f for f in report["lines"][line]["figures"]}  # type: ignore[index]


def _executed(**kw: object) -> dict[str, object]:
    base: dict[str, object] = {
        "line": 2,
        "status": "completed",
        "reason": None,
        "end_t_s": 119.5,
        "p_mission_est_m": [3.1, 0.5],
        "heading_est_rad": 0.205,
        "aqf": "Fine",
        "imu_integration_s": 51.0,
        "position_sigma_m": 0.2,
        "hga_margin_predicted_deg": None,
    }
    base.update(kw)
    return base


def test_percentiles_count_ties_half() -> None:
    assert percentile_of(2.0, [1.0, 2.0, 2.0, 3.0]) == 50.0
    assert percentile_of(0.0, [1.0, 2.0]) == 0.0 and percentile_of(5.0, [1.0, 2.0]) == 100.0
    assert percentile_of(1.0, [1.0]) == 50.0
    assert percentile_of(1.0, [math.nan]) is None and percentile_of(math.nan, [1.0]) is None


def test_a_typical_execution_sits_inside_its_distributions() -> None:
    outcomes = _outcomes()
    risk = risk_table(SEQUENCE, outcomes)
    report = json.loads(
        json.dumps(predicted_vs_executed(risk, outcomes, [_executed()]), allow_nan=False)
    )
    assert report["flags"] == [] and report["truth"] is None
    assert report["lines"][0]["command"] == "DRIVE_STRAIGHT distance_m=3.0"
    f = _figures(report)
    assert f["end_t_s"]["percentile"] == 50.0  # 20 of 40 below 119.5
    assert f["imu_integration_s"]["percentile"] == 37.5  # 10 below, 10 tied: (10 + 5) / 40
    assert f["position_sigma_m"]["percentile"] == 50.0  # all tied
    hga = f["hga_margin_predicted_deg"]
    assert (hga["executed"], hga["percentile"], hga["outside_95"]) == (None, None, False)
    assert f["status"] == {
        "name": "status",
        "executed": "completed",
        "probability": 0.9,
        "outside_95": False,
    }
    fit = risk["lines"][0]["end_est"]
    d = np.array([3.1, 0.5]) - fit["mean_m"]
    assert f["end_est"]["mahalanobis2"] == pytest.approx(
        float(d @ np.linalg.solve(fit["cov_m2"], d))
    )
    assert f["end_est"]["outside_95"] is False and 0.0 <= f["end_est"]["percentile"] <= 100.0
    assert f["heading_est_deg"]["executed"] == pytest.approx(math.degrees(0.205))
    assert f["heading_est_deg"]["percentile"] == 52.5  # 21 of 40 below 0.205 rad


def test_what_fell_outside_95_is_flagged() -> None:
    outcomes = _outcomes()
    risk = risk_table(SEQUENCE, outcomes)
    far = [3.0 + 3.0 * math.sqrt(chi2.ppf(0.95, 2)) * 0.2, 0.5]  # 3x the 95 % ellipse North
    executed = [
        _executed(
            end_t_s=150.0, p_mission_est_m=far, status="halted",
            reason="keep-out zone rock: 0.10 m away", aqf="Coarse",
        )
    ]  # fmt: skip
    report = predicted_vs_executed(risk, outcomes, executed)
    f = _figures(report)
    assert f["end_t_s"]["percentile"] == 100.0 and f["end_t_s"]["outside_95"] is True
    assert f["end_est"]["outside_95"] is True and f["end_est"]["mahalanobis2"] > chi2.ppf(0.95, 2)
    assert f["status"]["probability"] == 0.1 and f["status"]["outside_95"] is False
    assert f["halt_reason"] == {
        "name": "halt_reason",
        "executed": "keepout",
        "probability": 0.0,
        "outside_95": True,
    }
    assert f["aqf"]["probability"] == 0.0 and f["aqf"]["outside_95"] is True
    assert report["flags"][0] == "line 2: end_t_s at the 100th percentile"
    assert report["flags"][1].startswith("line 2: end_est outside the 95 % ellipse (Mahalanobis² ")
    assert report["flags"][2:] == [
        "line 2: halt_reason keepout had a probability of 0.0 %",
        "line 2: aqf Coarse had a probability of 0.0 %",
    ]
    early = predicted_vs_executed(
        risk, outcomes, [_executed(end_t_s=100.5, imu_integration_s=50.0)]
    )
    g = _figures(early)
    assert g["end_t_s"]["percentile"] == 2.5 and g["end_t_s"]["outside_95"] is False  # 1 below
    assert g["imu_integration_s"]["percentile"] == 12.5 and early["flags"] == []


def test_the_truth_part_only_with_the_truth() -> None:
    outcomes = _outcomes()
    risk = risk_table(SEQUENCE, outcomes)
    truth = [
        {
            "line": 2,
            "p_mission_true_m": [3.0, 0.5],
            "max_tilt_true_deg": 12.0,
            "hga_margin_deg": None,
        }
    ]
    report = predicted_vs_executed(risk, outcomes, [_executed()], truth=truth)
    t = {f["name"]: f for f in report["truth"]["lines"][0]["figures"]}
    assert t["end_true"]["outside_95"] is False
    assert t["max_tilt_true_deg"]["percentile"] == 100.0  # every run's tilt is below 12
    assert t["hga_margin_deg"]["percentile"] is None
    assert report["truth"]["flags"] == ["line 2: max_tilt_true_deg at the 100th percentile"]
    assert report["flags"] == []  # the truth never reaches the operator's flags


def test_bad_executed_entries_are_refused() -> None:
    outcomes = _outcomes()
    risk = risk_table(SEQUENCE, outcomes)
    with pytest.raises(ValueError, match=r"executed\[0\].line"):
        predicted_vs_executed(risk, outcomes, [_executed(line=0)])
    with pytest.raises(ValueError, match=r"executed\[0\]: must be an object"):
        predicted_vs_executed(risk, outcomes, ["line 2"])  # type: ignore[list-item]
    with pytest.raises(ValueError, match="p_mission_est_m"):
        predicted_vs_executed(risk, outcomes, [_executed(p_mission_est_m="north")])
    with pytest.raises(ValueError, match="end_t_s: must be a number"):
        predicted_vs_executed(risk, outcomes, [_executed(end_t_s="late")])
