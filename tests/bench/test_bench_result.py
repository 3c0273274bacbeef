"""``bench.result.misses``: the targets a result missed, each with its metric, value and
target, so that every bench can say what it missed (issue 21)."""

import math

from bench.result import bench_result, misses, target_text


def test_misses_lists_each_missed_target_with_its_value() -> None:
    result = bench_result(
        "demo",
        {"wall_s": 6.0, "pct": 90.75, "ratio": 1.2},
        {"wall_s": {"le": 5.0}, "pct": {"ge": 97.0}, "ratio": {"ge": 1.0, "le": 2.0}},
    )
    assert result["ok"] is False
    assert misses(result) == [
        {"metric": "wall_s", "value": 6.0, "target": {"le": 5.0}},
        {"metric": "pct", "value": 90.75, "target": {"ge": 97.0}},
    ]


def test_a_figure_that_does_not_exist_misses_its_target() -> None:
    # NaN becomes null in the result (JSON has no NaN) and meets no target
    result = bench_result("demo", {"gap_m": math.nan}, {"gap_m": {"le": 1.0}})
    assert misses(result) == [{"metric": "gap_m", "value": None, "target": {"le": 1.0}}]


def test_misses_agrees_with_ok() -> None:
    result = bench_result("demo", {"wall_s": 0.5}, {"wall_s": {"le": 1.0}})
    assert result["ok"] is True and misses(result) == []


def test_target_text() -> None:
    assert target_text({"le": 5.0}) == "≤ 5"
    assert target_text({"ge": 97.0}) == "≥ 97"
    assert target_text({"ge": 1.0, "le": 2.5}) == "≥ 1 and ≤ 2.5"
