"""When a step starts (sequences.timing), on a toy clock whose sols are 100 s long."""

from __future__ import annotations

from sequences.language import TimeTag, parse
from sequences.timing import start_time


def sol_of(t_s: float) -> int:
    return int(t_s // 100.0)


def time_at(sol: int, lmst_h: float) -> float:
    return 100.0 * sol + 100.0 * lmst_h / 24.0


def _tag(line: str) -> TimeTag:
    return parse(f"SEQUENCE t\n{line}\n").steps[0].time_tag


def test_each_kind_of_tag() -> None:
    assert start_time(_tag("WAIT duration_s=1"), 250.0, 240.0, sol_of, time_at) == 250.0
    assert start_time(_tag("@ +30s WAIT duration_s=1"), 250.0, 240.0, sol_of, time_at) == 270.0
    # 12:00 LMST: 50 s into a sol; at 230 (sol 2, 30 s in) it is still to come today ...
    assert start_time(_tag("@ 12:00 LMST WAIT duration_s=1"), 230.0, 0.0, sol_of, time_at) == 250.0
    # ... at 260 it has passed: tomorrow's
    assert start_time(_tag("@ 12:00 LMST WAIT duration_s=1"), 260.0, 0.0, sol_of, time_at) == 350.0
    tag = _tag("@ sol 7 06:00 LMST WAIT duration_s=1")
    assert start_time(tag, 260.0, 0.0, sol_of, time_at) == 725.0
