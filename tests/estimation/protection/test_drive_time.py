"""The flight software's LMST against the simulator's Mars24 clock, and the limits on time."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimation.protection.drive_time import lmst_h, past_time_of_day
from sim.world.marsclock import lmst_h_from_t_s


@pytest.mark.parametrize("lon_east_deg", [175.47, 354.47, 0.0])
def test_lmst_agrees_with_the_truth_clock(lon_east_deg: float) -> None:
    t = np.linspace(1.3e8, 1.3e8 + 3 * 88775.244, 97)
    ours = np.array([lmst_h(float(x), math.radians(lon_east_deg)) for x in t])
    truth = lmst_h_from_t_s(t, (360.0 - lon_east_deg) % 360.0)
    wrapped = (ours - truth + 12.0) % 24.0 - 12.0
    assert float(np.max(np.abs(wrapped))) * 3600.0 < 1.0  # within a second


def test_the_time_of_day_limit_is_reached_once_after_the_start() -> None:
    assert not past_time_of_day(14.0, 14.9, 15.0)
    assert past_time_of_day(14.0, 15.0, 15.0)
    assert past_time_of_day(23.0, 0.5, 0.25)  # across midnight
    assert not past_time_of_day(23.0, 23.5, 0.25)
