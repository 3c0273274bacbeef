"""A bench that misses a target says which (issue 21: ``roverops bench sim`` exited 1
without naming the target it missed): the metric, its value and the target, on stderr,
with ``--json`` too (stdout stays the one JSON object); and the human output shows the
targets as text, not as dicts."""

import json
from typing import Any

import pytest

from bench.result import bench_result
from cli.main import build_parser
from cli.output import print_result


def _printed(
    result: dict[str, Any], as_json: bool, capsys: pytest.CaptureFixture[str]
) -> "pytest.CaptureResult[str]":
    """What ``roverops bench sim`` prints for ``result``: its printer, chosen as main does."""
    args = build_parser().parse_args(["bench", "sim", *(["--json"] if as_json else [])])
    getattr(args, "printer", print_result)(result, args.json)
    return capsys.readouterr()


MISSED = bench_result(
    "sim",
    {"drive_100m_wall_s": 6.25, "idle_sol_wall_s": 0.0008, "session_over_world_ratio": 2.5},
    {
        "drive_100m_wall_s": {"le": 5.0},
        "idle_sol_wall_s": {"le": 0.5},
        "session_over_world_ratio": {"le": 2.0},
    },
)


@pytest.mark.parametrize("as_json", [False, True])
def test_a_missed_target_is_named_on_stderr(
    as_json: bool, capsys: pytest.CaptureFixture[str]
) -> None:
    printed = _printed(MISSED, as_json, capsys)
    missed = [line for line in printed.err.splitlines() if "missed" in line]
    assert len(missed) == 2, printed.err
    assert "drive_100m_wall_s" in missed[0] and "6.25" in missed[0] and "≤ 5" in missed[0]
    assert "session_over_world_ratio" in missed[1] and "2.5" in missed[1]
    assert "idle_sol_wall_s" not in printed.err
    if as_json:
        assert json.loads(printed.out) == MISSED


def test_a_bench_that_meets_its_targets_prints_nothing_on_stderr(
    capsys: pytest.CaptureFixture[str],
) -> None:
    met = bench_result("sim", {"idle_sol_wall_s": 0.0008}, {"idle_sol_wall_s": {"le": 0.5}})
    printed = _printed(met, False, capsys)
    assert printed.err == ""
    assert "idle_sol_wall_s: ≤ 0.5" in printed.out
    assert "{" not in printed.out and "'" not in printed.out
