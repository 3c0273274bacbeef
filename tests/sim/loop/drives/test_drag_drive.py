"""Wheel-drag driving in the loop (issue 22 item 3; Spirit from sol 125, Cheng, Maimone and
Matthies 2005 sec. 4.2): a DRIVE_STRAIGHT with ``drag_wheel=rf`` veers right and its
encoder barely turns; SAPP, told by the command, averages the five driven wheels and ends
closer to the truth than when the same wheel fails unannounced (``RoverSim.failed_wheel``,
six wheels averaged); the failed wheel is plain data in the simulator's checkpoint. And a
drive with no dragged wheel is bit for bit what it was before wheel drag came in (values
recorded on the code before the change, as float hex)."""

from __future__ import annotations

import numpy as np
import pytest

from estimation.sapp.aqf import AttitudeQuality
from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.rover_sim import RoverSim
from sim.loop.session import RoverSession
from tests.sim.loop.test_session_helpers import START


def _drive(drag_wheel: str | None, failed_wheel: str | None) -> tuple[RoverSession, float]:
    """A 3 m drive on the level bedrock site; the estimate's distance from the truth (m)."""
    session = RoverSession("flat", 2, START)
    session.nate.load_attitude(session.q_b_ll_true(), AttitudeQuality.FINE)
    session.sim.failed_wheel = failed_wheel
    p0, e0 = session.sim.drive_state.p_s.copy(), session.nate.p_s.copy()
    report = session.execute(cmd.DriveStraight(3.0, drag_wheel=drag_wheel))
    assert report.status == "completed"
    moved = session.sim.drive_state.p_s[:2] - p0[:2]
    return session, float(np.linalg.norm(session.nate.p_s[:2] - e0[:2] - moved))


def test_a_commanded_drag_veers_right_and_five_wheel_odometry_beats_an_unannounced_one() -> None:
    told, err_told = _drive("rf", None)
    untold, err_untold = _drive(None, "rf")
    # the same truth either way: the simulator drags rf in both
    np.testing.assert_array_equal(told.sim.drive_state.p_s, untold.sim.drive_state.p_s)
    assert told.sim.drive_state.yaw_rad > np.radians(3.0)  # towards the right wheel
    rolled = told.sim.drive_state.wheel_angle_rad * 0.13
    assert rolled[3] < 0.1 * rolled[0]
    assert err_told < 0.5 * err_untold
    assert err_told < 0.06 * 3.0  # what is left is the driven wheels' slip on bedrock


def test_failed_wheel_is_checked_and_kept_in_the_checkpoint() -> None:
    sim = RoverSim("flat", 1, START)
    assert sim.failed_wheel is None and sim.state()["failed_wheel"] is None
    with pytest.raises(InputError, match="failed_wheel"):
        sim.failed_wheel = "front"
    sim.failed_wheel = "lm"
    again = RoverSim("flat", 1, START)
    again.load_state(sim.state())
    assert again.failed_wheel == "lm"
    old = sim.state()
    del old["failed_wheel"]  # a checkpoint from before wheel drag
    again.load_state(old)
    assert again.failed_wheel is None


def test_a_drive_without_drag_is_bit_identical_to_before() -> None:
    session = RoverSession("gusev", 11, START)
    for c in (
        cmd.DriveStraight(1.5),
        cmd.DriveArc(radius_m=-3.0, angle_deg=15.0),
        cmd.TurnInPlace(angle_deg=20.0),
    ):
        assert session.execute(c).status == "completed"
    sim, nate = session.sim, session.nate
    assert [float(x).hex() for x in sim.drive_state.p_s] == [
        "0x1.219036ff8a106p+1",
        "-0x1.1400e6be47a80p-3",
        "0x1.1f706d23d3e45p-8",
    ]
    assert [float(x).hex() for x in sim.drive_state.q_s_b] == [
        "-0x1.1bfde8e58a868p-6",
        "-0x1.09f28e701c295p-4",
        "0x1.1a47e31a6b7e3p-5",
        "0x1.fe89adc746a8bp-1",
    ]
    assert sim.wheel_angle_rad_now().tolist() == [
        19.04878525565391,
        17.982738148535773,
        19.04852345626611,
        16.44859373603276,
        17.17718143227779,
        16.44859373603276,
    ]
    assert [float(x).hex() for x in nate.p_s] == [
        "0x1.2367a71bc1496p+1",
        "-0x1.a1a892cf97099p-4",
        "0x1.26d65d4c348fbp-11",
    ]
    assert [float(x).hex() for x in nate.q_b_ll] == [
        "-0x1.4339ce7c2b7dcp-7",
        "0x1.0e90807088a6ap-11",
        "-0x1.204d3a0a749fap-5",
        "0x1.ffa86827de750p-1",
    ]
