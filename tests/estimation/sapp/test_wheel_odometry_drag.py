"""Wheel odometry with a dragged wheel (the drive command's ``drag_wheel``; Spirit's right
front from sol 125, Cheng, Maimone and Matthies 2005 sec. 4.2): eqs. (5)-(7) average the
five driven wheels, the many-cycle form agrees with the one-cycle form, NATE carries the
dragged wheel through a checkpoint, and bad names are refused naming the parameter."""

from __future__ import annotations

import numpy as np
import pytest

from estimation.geometry import WHEEL_KEYS, driven_wheels, wheel_index
from estimation.sapp import wheel_odometry as wo
from estimation.sapp.nate import DriveCommand, Nate, NateMode
from estimation.sapp.nate_io import EncoderSample, ImuSample
from estimation.sapp.wheel_odometry import DriveKind
from tests.estimation.sapp.test_nate import LAT, LON, T0


def test_eq5_with_a_dragged_wheel_is_the_mean_of_the_five_driven() -> None:
    a = np.array([0.010, 0.011, 0.012, 0.001, 0.013, 0.014])  # rf dragged: rolls little
    step = wo.odometry_step(DriveKind.STRAIGHT, a / 0.13, np.zeros(6), drag_wheel="rf")
    assert step.delta_p_b[0] == pytest.approx(np.mean(a[[0, 1, 2, 4, 5]]), abs=1e-15)
    assert step.used.tolist() == [True, True, True, False, True, True]
    six = wo.odometry_step(DriveKind.STRAIGHT, a / 0.13, np.zeros(6))
    assert six.delta_p_b[0] == pytest.approx(np.mean(a), abs=1e-15)


def test_eq6_leaves_the_dragged_wheel_out_of_psi_ave() -> None:
    centre = wo.arc_centre_b(3.0)
    r = wo.FLIGHT_GEOMETRY.wheel_xy_b() - centre
    steer = np.zeros(6)
    steer[[0, 2, 3, 5]] = np.arctan2(r[[0, 2, 3, 5], 0], -r[[0, 2, 3, 5], 1])  # tangent
    psi = 0.01
    a = psi * np.hypot(r[:, 0], r[:, 1])
    a[1] = 0.0  # lm dragged: no roll to speak of
    step = wo.odometry_step(DriveKind.ARC, a / 0.13, steer, centre, drag_wheel="lm")
    assert step.delta_heading_rad == pytest.approx(psi, rel=1e-12)
    assert np.isnan(step.psi_rad[1]) and not step.used[1]


@pytest.mark.parametrize("kind", [DriveKind.STRAIGHT, DriveKind.ARC, DriveKind.TURN_IN_PLACE])
@pytest.mark.parametrize("wheel", ["lf", "rm"])
def test_many_cycles_at_once_are_the_cycles_one_by_one(kind: DriveKind, wheel: str) -> None:
    rng = np.random.default_rng(22)
    rotation = rng.normal(0.02, 0.01, (50, 6))
    steer = wo.steer_six(rng.uniform(-0.5, 0.5, (50, 4)))
    centre = wo.arc_centre_b(-2.0) if kind is DriveKind.ARC else None
    dp_b, heading = wo.odometry_deltas(kind, rotation, steer, centre, drag_wheel=wheel)
    for k in range(50):
        one = wo.odometry_step(kind, rotation[k], steer[k], centre, drag_wheel=wheel)
        assert np.allclose(dp_b[k], one.delta_p_b, rtol=0.0, atol=1e-15)
        assert heading[k] == pytest.approx(one.delta_heading_rad, abs=1e-15)


def test_wheel_names_and_bad_ones() -> None:
    assert [wheel_index(k) for k in WHEEL_KEYS] == list(range(6))
    assert driven_wheels(None).all()
    with pytest.raises(ValueError, match=r"^drag_wheel: must be one of"):
        wo.odometry_step(DriveKind.STRAIGHT, np.zeros(6), np.zeros(6), drag_wheel="front")
    with pytest.raises(ValueError, match=r"^drive\.drag_wheel: must be one of"):
        Nate(LAT, LON, T0).mobility(DriveCommand(drag_wheel="RF"))


def test_nate_odometry_uses_the_commands_driven_wheels_and_keeps_them_in_a_checkpoint() -> None:
    nate = Nate(LAT, LON, T0)
    nate.mobility(DriveCommand(DriveKind.STRAIGHT, drag_wheel="rr"), wheel_angle_rad=np.zeros(6))
    restored = Nate(LAT, LON, T0)
    assert nate.state()["drive_drag_wheel"] == "rr"
    restored.load_state(nate.state())
    wheels = np.full(6, 1.0)
    wheels[5] = 0.05  # the dragged wheel barely turns
    imu = ImuSample(np.zeros(3), np.array([0.0, 0.0, -3.711 * 0.125]), 0.125, True)
    for n in (nate, restored):
        n.step(imu, EncoderSample(wheels, np.zeros(6)))
        assert n.mode is NateMode.MOBILITY
        assert n.p_s[0] == pytest.approx(0.13, rel=1e-4)  # 1 rad of the five driven wheels
    np.testing.assert_array_equal(restored.p_s, nate.p_s)
