"""The slip check on known motions: sol 603's stop, VO failures in a row."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimation.protection.limits import MobilityLimits
from estimation.protection.monitor import MobilityProtection
from estimation.protection.slip_check import slip_fraction

P0 = np.zeros(3)


def _monitor(**overrides: object):  # type: ignore[no-untyped-def]
    protection = MobilityProtection(math.radians(175.5))
    limits = protection.drive_limits(**overrides)  # type: ignore[arg-type]
    return protection.begin_drive(1.0e8, 0.0, limits)


def test_slip_from_known_motions() -> None:
    assert slip_fraction(5.0, 5.0) == 0.0
    assert slip_fraction(0.0, 5.0) == 1.0
    assert slip_fraction(-1.0, 4.0) == 1.25  # slid back: MER measured up to 125 %
    with pytest.raises(ValueError, match="wheel_m"):
        slip_fraction(1.0, 0.0)


def test_sol_603_stops_after_its_first_5_m_segment_at_44_5_percent() -> None:
    monitor = _monitor()
    # ten 0.5 m steps; VO saw 55.5 % of the wheels' motion in each
    halts = [monitor.after_vo_step(1.0e8 + i, P0, 0.5, 0.5, 0.2775) for i in range(10)]
    assert halts[:9] == [None] * 9
    halt = halts[9]
    assert halt is not None and halt.check == "slip"
    assert halt.values["slip"] == pytest.approx(0.445)
    assert "44.5 %" in halt.reason and "40 %" in halt.reason


def test_a_slip_under_the_limit_goes_on_and_a_drivers_limit_counts() -> None:
    monitor = _monitor()
    assert all(monitor.after_vo_step(0.0, P0, 0.5, 0.5, 0.35) is None for _ in range(20))
    strict = _monitor(slip_limit=0.2)
    halts = [strict.after_vo_step(0.0, P0, 0.5, 0.5, 0.35) for _ in range(10)]
    assert halts[-1] is not None and halts[-1].values["slip_limit"] == 0.2


@pytest.mark.parametrize(("policy", "halts"), [("halt", True), ("continue", False)])
def test_vo_failures_in_a_row_halt_or_continue_as_commanded(policy: str, halts: bool) -> None:
    monitor = _monitor(vo_fail=policy)
    limit = MobilityLimits().vo_max_failures_in_row
    out = [monitor.after_vo_step(0.0, P0, 0.3, 0.3, None) for _ in range(limit)]
    assert out[:-1] == [None] * (limit - 1)
    assert (out[-1] is not None and out[-1].check == "vo_fail") is halts
    with pytest.raises(ValueError, match="vo_fail"):
        _monitor(vo_fail="maybe")
