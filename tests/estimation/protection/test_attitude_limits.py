"""Roll and pitch from a known gravity vector, and the 1 s smoothing of the accelerometers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.protection.attitude_limits import (
    TILT_WINDOW_CYCLES,
    first_over,
    roll_pitch_rad,
    smoothed_specific_force,
    tilt_rad,
)

G = 3.711


@pytest.mark.parametrize(("roll_deg", "pitch_deg"), [(0, 0), (12, -7), (-25, 31), (40, 5)])
def test_roll_and_pitch_from_a_known_gravity_vector(roll_deg: float, pitch_deg: float) -> None:
    # body from LL by yaw-pitch-roll (aerospace order, z down): the specific force at rest
    # is minus gravity, (0, 0, -g) in LL, expressed in the body (scipy, independent of us)
    R_ll_b = Rotation.from_euler("ZYX", [33.0, pitch_deg, roll_deg], degrees=True)
    f_b = R_ll_b.inv().apply([0.0, 0.0, -G])
    roll, pitch = roll_pitch_rad(f_b[None, :])
    assert math.degrees(float(roll[0])) == pytest.approx(roll_deg, abs=1e-9)
    assert math.degrees(float(pitch[0])) == pytest.approx(pitch_deg, abs=1e-9)
    body_z_ll = R_ll_b.apply([0.0, 0.0, 1.0])
    assert tilt_rad(float(roll[0]), float(pitch[0])) == pytest.approx(math.acos(body_z_ll[2]))


def test_a_short_jolt_is_averaged_a_lasting_tilt_is_not() -> None:
    n, dt = 40, 0.125
    f = np.tile([0.0, 0.0, -G], (n, 1))
    f[10] = [G, 0.0, -G]  # one cycle's jolt forwards: 45 deg if read alone
    f[20:] = [G * math.sin(0.6), 0.0, -G * math.cos(0.6)]  # pitched up 0.6 rad from cycle 20
    smoothed = smoothed_specific_force(f * dt, np.full(n, dt))
    _, pitch = roll_pitch_rad(smoothed)
    assert float(np.max(np.abs(pitch[:20]))) < math.radians(8.0)
    assert first_over(pitch, 0.5) == 20 + TILT_WINDOW_CYCLES - 2  # the window fills with it
    assert pitch[-1] == pytest.approx(0.6)
    with pytest.raises(ValueError, match="dt_s"):
        smoothed_specific_force(f * dt, np.zeros(n))
