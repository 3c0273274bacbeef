"""A drive with no dragged wheel is bit for bit what it was before wheel-drag driving came
in: the truth, the encoders and SAPP's estimate after a straight drive, an arc and a turn
on Gusev (values recorded on the code before the change, as float hex)."""

from sequences import commands as cmd
from sim.loop.session import RoverSession
from tests.sim.loop.test_session_helpers import START


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
