"""The risk table (server.rehearsal.risk) on hand-made outcomes, against independent
references: scipy's χ² quantiles, fresh Monte Carlo draws from a known Gaussian, numpy's
percentiles, counts by hand; its verdicts; no NaN in its JSON whatever the runs."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.stats import chi2

from estimation.protection.keepout import KeepOutZone
from server.rehearsal.risk import (
    chi2_2dof_k2,
    ellipse,
    halt_reason,
    inside_ellipse,
    risk_table,
    zones_in_mission,
)
from sim.rehearsal.inputs import ReportedStart
from sim.rehearsal.outcome import RunOutcome, StepOutcome

SEQUENCE = "SEQUENCE r\nDRIVE_STRAIGHT distance_m=3.0\n# a comment\nHGA_PASS duration_min=10\n"
DRIVE_LINE, HGA_LINE = 2, 4


def _step(line: int, **kw: object) -> StepOutcome:
    base: dict[str, object] = {
        "line": line,
        "command": "X",
        "status": "completed",
        "reason": None,
        "start_t_s": 100.0,
        "end_t_s": 200.0,
        "p_mission_true_m": (0.0, 0.0),
        "p_mission_est_m": (0.0, 0.0),
        "heading_true_rad": 0.0,
        "heading_est_rad": 0.0,
        "max_tilt_true_deg": 5.0,
        "aqf": "Fine",
        "imu_integration_s": 10.0,
        "position_sigma_m": 0.1,
    }
    base.update(kw)
    return StepOutcome(**base)  # type: ignore[arg-type]


def _runs(
    drive: list[dict[str, object]], hga: list[dict[str, object]] | None = None
) -> list[RunOutcome]:
    hga = hga or [{} for _ in drive]
    return [
        RunOutcome(i, 0, (_step(DRIVE_LINE, **d), _step(HGA_LINE, **h)))
        for i, (d, h) in enumerate(zip(drive, hga, strict=True))
    ]


def _json(table: dict[str, object]) -> dict[str, object]:
    return json.loads(json.dumps(table, allow_nan=False))  # type: ignore[no-any-return]


def test_chi2_quantiles_match_scipy() -> None:
    for p in (0.1, 0.5, 0.9, 0.95, 0.99):
        assert chi2_2dof_k2(p) == pytest.approx(chi2.ppf(p, 2), rel=1e-12)
    assert chi2_2dof_k2(0.95) == pytest.approx(5.991, abs=5e-4)
    with pytest.raises(ValueError, match="p"):
        chi2_2dof_k2(1.0)


def test_ellipse_axes_and_angle_from_a_known_covariance() -> None:
    # σ 2 m along the North-East diagonal, 0.5 m across it
    c, s = math.cos(math.radians(45.0)), math.sin(math.radians(45.0))
    rot = np.array([[c, -s], [s, c]])
    cov = rot @ np.diag([4.0, 0.25]) @ rot.T
    e = ellipse(cov, 0.95)
    assert e["a_m"] == pytest.approx(2.0 * math.sqrt(chi2.ppf(0.95, 2)), rel=1e-9)
    assert e["b_m"] == pytest.approx(0.5 * math.sqrt(chi2.ppf(0.95, 2)), rel=1e-9)
    assert e["angle_deg"] == pytest.approx(45.0, abs=1e-9)
    assert ellipse(np.diag([0.1, 3.0]), 0.5)["angle_deg"] == pytest.approx(90.0)  # East
    assert ellipse(np.diag([3.0, 0.1]), 0.5)["angle_deg"] == pytest.approx(0.0)  # North
    assert ellipse(np.zeros((2, 2)), 0.95) == {"a_m": 0.0, "b_m": 0.0, "angle_deg": 0.0}


def test_the_fitted_ellipses_cover_fresh_draws_at_their_probability() -> None:
    rng = np.random.default_rng(2025)
    mean = np.array([5.0, -3.0])
    cov = np.array([[0.8, 0.3], [0.3, 0.2]])
    drawn = rng.multivariate_normal(mean, cov, size=3000)
    table = risk_table(SEQUENCE, _runs([{"p_mission_true_m": tuple(p)} for p in drawn]))
    fit = table["lines"][0]["end_true"]
    np.testing.assert_allclose(fit["mean_m"], drawn.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(fit["cov_m2"], np.cov(drawn.T), atol=1e-12)
    fresh = rng.multivariate_normal(mean, cov, size=4000)
    for p in (0.5, 0.95):
        share = np.mean([inside_ellipse(x, fit["mean_m"], fit["cov_m2"], p) for x in fresh])
        assert abs(share - p) < 0.025, (p, share)  # binomial σ <= 0.008
    # the ellipse's own geometry agrees: a point on its major axis at a_m is on its edge
    e = fit["ellipse_95"]
    axis = np.array(
        [math.cos(math.radians(e["angle_deg"])), math.sin(math.radians(e["angle_deg"]))]
    )
    assert inside_ellipse(
        np.array(fit["mean_m"]) + 0.999 * e["a_m"] * axis, fit["mean_m"], fit["cov_m2"], 0.95
    )
    assert not inside_ellipse(
        np.array(fit["mean_m"]) + 1.001 * e["a_m"] * axis, fit["mean_m"], fit["cov_m2"], 0.95
    )


def test_probabilities_percentiles_and_histogram_by_hand() -> None:
    n = 20
    drive = []
    for i in range(n):
        d: dict[str, object] = {
            "end_t_s": 1000.0 + i,
            "max_tilt_true_deg": float(i),
            "aqf": "Fine" if i < 15 else "Coarse",
        }
        if i in (0, 1, 2):
            d |= {
                "status": "halted",
                "reason": "tilt limit: roll 31.0 deg, pitch 2.0 deg > 30.0 deg",
            }
        if i == 3:
            d |= {"status": "halted", "reason": "slip check: slip 40.0 % over 1.00 m"}
        if i == 4:
            d |= {"keepouts_entered": ("rock1", "rock1")}
        drive.append(d)
    hga = [
        {"status": "not_run"} if i < 4 else {"hga_margin_deg": 1.0 + i, "end_t_s": 5000.0 + i}
        for i in range(n)
    ]
    table = _json(risk_table(SEQUENCE, _runs(drive, hga)))
    assert table["runs"] == n and [x["line"] for x in table["lines"]] == [DRIVE_LINE, HGA_LINE]
    first, second = table["lines"]
    assert first["command"] == "DRIVE_STRAIGHT distance_m=3.0"
    assert first["status"] == {
        "completed": 0.8,
        "refused": 0.0,
        "failed": 0.0,
        "halted": 0.2,
        "not_run": 0.0,
    }
    assert first["halts"] == {"slip": 0.05, "tilt": 0.15}
    assert first["keepouts"] == {"rock1": 0.05}
    assert first["aqf"] == {"Fine": 0.75, "Coarse": 0.25}
    # linear interpolation on 1000..1019: p5 = 1000 + 0.05 * 19
    assert first["end_t_s"] == pytest.approx({"p5": 1000.95, "p50": 1009.5, "p95": 1018.05})
    tilt = first["max_tilt_deg"]
    assert (tilt["max"], sum(tilt["hist"]["counts"])) == (19.0, n)
    edges = tilt["hist"]["edges_deg"]
    assert edges[0] == 0.0 and edges[-1] > 19.0
    assert tilt["hist"]["counts"] == list(np.histogram(np.arange(20.0), bins=edges)[0])
    assert first["hga_margin_deg"] is None and first["hga_margin_predicted_deg"] is None
    # the second step ran in 16 runs: its percentiles are over those
    assert second["status"]["not_run"] == 0.2
    assert second["hga_margin_deg"] == pytest.approx(
        dict(
            zip(("p5", "p50", "p95"), np.percentile(np.arange(5.0, 21.0), [5, 50, 95]), strict=True)
        )
    )
    assert table["end_t_s"]["p5"] == pytest.approx(
        float(np.percentile([1000.0 + i for i in range(4)] + [5000.0 + i for i in range(4, n)], 5))
    )


def test_verdicts_and_their_reasons() -> None:
    def line_of(drive: list[dict[str, object]], **kw: object) -> dict[str, object]:
        return risk_table(SEQUENCE, _runs(drive), **kw)["lines"][0]  # type: ignore[no-any-return]

    calm = [{"p_mission_true_m": (0.01 * i, 0.02 * (i % 7))} for i in range(100)]
    assert line_of(calm)["verdict"] == "ok" and line_of(calm)["why"] == []
    halts = [dict(d) for d in calm]
    for i in range(6):
        halts[i] |= {"status": "halted", "reason": "tilt"}
    line = line_of(halts)
    assert line["verdict"] == "risk" and line["why"] == ["halt 6 % (tilt 6 %)"]
    for i in range(4):
        halts[i] = dict(calm[i])
    line = line_of(halts)
    assert line["verdict"] == "caution" and line["why"] == ["halt 2 % (tilt 2 %)"]
    steep = [dict(d, max_tilt_true_deg=25.0 + 0.1 * i) for i, d in enumerate(calm)]
    assert line_of(steep)["verdict"] == "risk"  # p95 34.4 deg > 30
    assert line_of(steep, tilt_limit_deg=40.0)["verdict"] == "ok"
    assert line_of(steep, tilt_limit_deg=34.8)["verdict"] == "caution"  # max 34.9 beyond it
    # a zone clear of every run but inside the 95 % ellipse's reach: caution
    near = KeepOutZone.circle("rock1", -1, 1.1, 0.06, 0.05)
    line = line_of(calm, keepout_zones_mission=[near])
    assert line["keepouts"] == {"rock1": 0.0}
    assert line["verdict"] == "caution" and line["why"] == ["95 % ellipse reaches keep-out rock1"]
    far = KeepOutZone.polygon("wall", -1, [(5.0, 5.0), (6.0, 5.0), (6.0, 6.0)])
    assert line_of(calm, keepout_zones_mission=[far])["verdict"] == "ok"


def test_halt_reasons_are_named_by_their_check() -> None:
    assert halt_reason("tilt") == "tilt"
    assert halt_reason("keep-out zone rock1: 0.20 m away after the VO update") == "keepout"
    assert halt_reason("VO failed 3 steps in a row: slip unknown (vo_fail=halt)") == "vo_fail"
    assert halt_reason("drive timeout: 900 s > 800 s") == "timeout"
    assert halt_reason("suspension limit: rocker 21.0 deg") == "suspension"
    assert halt_reason("something new") == "other" and halt_reason(None) == "other"


def test_degenerate_campaigns_give_json_without_nan() -> None:
    one = _json(risk_table(SEQUENCE, _runs([{"p_mission_true_m": (1.0, 2.0)}])))
    fit = one["lines"][0]["end_true"]
    assert fit["mean_m"] == [1.0, 2.0] and fit["cov_m2"] == [[0.0, 0.0], [0.0, 0.0]]
    assert fit["ellipse_95"] == {"a_m": 0.0, "b_m": 0.0, "angle_deg": 0.0}
    assert inside_ellipse((1.0, 2.0), fit["mean_m"], fit["cov_m2"], 0.95)
    assert not inside_ellipse((1.0, 2.001), fit["mean_m"], fit["cov_m2"], 0.95)
    refused = [
        {"status": "refused", "reason": "NATE refuses", "p_mission_true_m": (math.nan, math.nan)}
    ] * 5
    table = _json(risk_table(SEQUENCE, _runs(refused, [{"status": "not_run"}] * 5)))
    first, second = table["lines"]
    assert first["status"]["refused"] == 1.0 and first["verdict"] == "risk"
    assert first["end_true"] is None and first["end_est"]["mean_m"] == [0.0, 0.0]
    assert second["status"]["not_run"] == 1.0
    assert all(
        second[k] is None
        for k in ("end_true", "end_est", "max_tilt_deg", "end_t_s", "heading_true_deg")
    )
    assert second["aqf"] == {} and second["verdict"] == "ok"
    empty = _json(risk_table(SEQUENCE, []))
    assert empty["runs"] == 0 and empty["end_t_s"] is None and empty["paths"] == []
    assert [x["status"]["not_run"] for x in empty["lines"]] == [0.0, 0.0]


def test_headings_across_north_and_the_paths_drawn() -> None:
    headings = [math.radians(359.0 + 0.02 * i) % (2 * math.pi) for i in range(101)]  # 359..361
    path = tuple((0.01 * k, 0.0) for k in range(500))
    table = risk_table(
        SEQUENCE, _runs([{"heading_true_rad": h, "path_true_m": path} for h in headings])
    )
    h = table["lines"][0]["heading_true_deg"]
    assert h["p5"] < h["p50"] < h["p95"] and h["p95"] - h["p5"] < 2.0
    assert min(abs(h["p50"] - 0.0), abs(h["p50"] - 360.0)) < 0.05
    assert len(table["paths"]) == 100 and all(len(p) == 200 for p in table["paths"])
    assert table["paths"][0][0] == [0.0, 0.0] and table["paths"][0][-1] == [4.99, 0.0]


def test_reported_zones_move_into_the_mission_frame() -> None:
    start = ReportedStart(
        site="gusev", mission="spirit", t_s=0.0, q_b_ll_est=(0.0, 0.0, 0.0, 1.0),
        p_s_est=(1.0, 1.0, 0.0), p_mission_est=(11.0, 21.0, 0.0), site_index=2,
        keepout_zones=(
            KeepOutZone.circle("rock", 2, 3.0, 4.0, 0.5),
            KeepOutZone.polygon("dune", 2, [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)]),
            KeepOutZone.circle("old", 1, 3.0, 4.0, 0.5),
        ),
    )  # fmt: skip
    moved = {z.name: z for z in zones_in_mission(start)}
    assert sorted(moved) == ["dune", "rock"]
    assert moved["rock"].centre_s == (13.0, 24.0) and moved["rock"].radius_m == 0.5
    assert moved["dune"].vertices_s == ((10.0, 20.0), (11.0, 20.0), (10.0, 21.0))
