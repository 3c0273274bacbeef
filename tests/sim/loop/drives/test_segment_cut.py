"""A drive halted by fault protection is cut at the cycle: the cut segment is the uncut
one's truth up to there (its slip draws included), and the rover stands where it stopped."""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np
import pytest

from sim.errors import InputError
from sim.loop.rover_sim import RoverSim, Segment

START = datetime(2004, 3, 1, 18, 0, tzinfo=UTC)


def _drives() -> list[tuple[str, tuple[float, ...]]]:
    return [("drive_straight", (2.0,)), ("drive_arc", (3.0, 0.5)), ("turn_in_place", (0.6,))]


@pytest.mark.parametrize(("method", "args"), _drives())
def test_a_cut_segment_is_the_uncut_one_up_to_the_cycle(
    method: str, args: tuple[float, ...]
) -> None:
    whole = getattr(RoverSim("gusev", 3, START), method)(*args)
    sim = RoverSim("gusev", 3, START)
    before = sim.state()
    getattr(sim, method)(*args)  # the drive as first computed, then loaded back
    sim.load_state(before)
    cycles = 15
    cut: Segment = getattr(sim, method)(*args, max_cycles=cycles)
    assert len(cut.truth) == cycles + 1
    # the planar motion and the slip exactly; the height within the settler's tolerance
    # (sim.rover.settle: 1e-4 m; it warm-starts along the path it is given)
    np.testing.assert_array_equal(cut.truth.p_s[:, :2], whole.truth.p_s[: cycles + 1, :2])
    np.testing.assert_array_equal(cut.truth.slip, whole.truth.slip[: cycles + 1])
    np.testing.assert_allclose(cut.truth.p_s[:, 2], whole.truth.p_s[: cycles + 1, 2], atol=1e-4)
    # the rover stands where the cut segment ended, at its time
    np.testing.assert_allclose(sim.drive_state.p_s, cut.truth.p_s[-1], atol=1e-9)
    assert sim.t_s == pytest.approx(float(cut.truth.t_s[-1]))
    assert len(whole.truth) > cycles + 1


def test_the_cut_takes_a_whole_number_of_cycles() -> None:
    sim = RoverSim("gusev", 3, START)
    for bad in (0, -3, 2.5, True):
        with pytest.raises(InputError, match="max_cycles"):
            sim.drive_straight(1.0, max_cycles=bad)  # type: ignore[arg-type]
