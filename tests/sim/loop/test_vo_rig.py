"""The VO rig and the VO pointing of a session: ``vo_rig=1024`` (a session option and
``SET_PARAM param=vo.rig``) images full Navcam frames and rebuilds the flight VO for them,
kept by a checkpoint; ``vo_az_deg``, ``vo_el_deg`` reach both the renderer and the flight VO,
and left out change nothing."""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Any

import numpy as np
import pytest
from numpy.typing import ArrayLike

from estimation.vo.odometry import VisualOdometry, VoResult
from estimation.vo.params import VoParams
from estimation.vo.stereo_rig import StereoRig
from sequences import commands as cmd
from sequences.validate import validate
from sim.errors import InputError
from sim.loop.rover_sim import RoverSim
from sim.loop.session import RoverSession
from sim.loop.vo_drive import VO_MAST_AZ_RAD, VO_MAST_EL_RAD, VO_RIG
from sim.sensors.navcam.camera import NavcamPair

START = datetime(2004, 4, 14, 15, 0, tzinfo=UTC)


class SeeingVO(VisualOdometry):
    """The flight VO, keeping the image shape and mast pointing of every step it is given."""

    def __init__(self, sim: RoverSim, rig: StereoRig) -> None:
        super().__init__(rig)
        self.seen: list[tuple[tuple[int, ...], float, float]] = []

    def step(self, left: ArrayLike, right: ArrayLike, **kw: Any) -> VoResult:
        self.seen.append((np.shape(left), kw["mast_az_rad"], kw["mast_el_rad"]))
        return super().step(left, right, **kw)


def _watch_pairs(session: RoverSession) -> list[NavcamPair]:
    """The pairs the simulator renders from now on (the real renderer, recorded)."""
    pairs: list[NavcamPair] = []
    render = session.sim.navcam_pair

    def recorded(*args: Any, **kwargs: Any) -> NavcamPair:
        pair = render(*args, **kwargs)
        pairs.append(pair)
        return pair

    session.sim.navcam_pair = recorded  # type: ignore[method-assign]
    return pairs


def test_a_1024_session_images_and_runs_vo_on_full_frames() -> None:
    session = RoverSession("gusev", 5, START, vo_rig=1024, visual_odometry=SeeingVO)
    vo = session.vo
    assert isinstance(vo, SeeingVO)
    assert vo.rig.camera.width_px == 1024 and vo.params == VoParams().for_width(1024)
    report = session.execute(cmd.DriveStraight(distance_m=0.7, vo=True))
    assert report.status == "completed", report.reason
    assert report.details["vo_steps"] == 1
    assert [shape for shape, _, _ in vo.seen] == [(1024, 1024)] * 2  # before and after the step
    assert sum(e.kind == "vo" for e in report.events) == 1  # an update or a failure, said


@pytest.mark.parametrize("bad", [512, 256.5, True, "1024", None])
def test_another_rig_is_refused(bad: object) -> None:
    with pytest.raises(InputError, match="vo_rig"):
        RoverSession("gusev", 5, START, vo_rig=bad)  # type: ignore[arg-type]


def test_set_param_changes_the_rig_and_a_checkpoint_keeps_it() -> None:
    session = RoverSession("gusev", 5, START)
    assert session.vo.rig == VO_RIG and session.state()["vo_rig"] == 256
    report = session.execute(cmd.SetParam(param="vo.rig", value=1024))
    assert report.status == "completed", report.reason
    assert any(e.text == "parameter vo.rig = 1024" for e in report.events)
    assert session.vo.rig.camera.width_px == 1024
    assert session.vo.params == VoParams().for_width(1024)
    state = session.state()
    assert state["vo_rig"] == 1024
    restored = RoverSession("gusev", 5, START)  # built as the original was: at 256
    restored.load_state(state)
    assert restored.vo.rig == session.vo.rig and restored.vo.params == session.vo.params
    # and back: a checkpoint at 256 loaded onto a 1024 session
    session.execute(cmd.SetParam(param="vo.rig", value=256))
    restored.load_state(session.state())
    assert restored.vo.rig == VO_RIG
    # a checkpoint from before the rig could change (no "vo_rig"): 256
    old = {k: v for k, v in state.items() if k != "vo_rig"}
    restored.load_state(old)
    assert restored.vo.rig == VO_RIG


@pytest.mark.parametrize(
    "param,value,match",
    [
        ("vo.rig", 512, r"value: vo\.rig must be 256 or 1024 \(px\), got 512"),
        ("vo.rig", True, r"value: vo\.rig must be 256 or 1024"),
        ("vo.size", 1024, r"param: vo\.size: no such VO setting"),
    ],
)
def test_set_param_of_a_bad_vo_setting_is_an_error(param: str, value: Any, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        cmd.SetParam(param=param, value=value)
    result = validate(f"SET_PARAM param={param} value={str(value).lower()}\n")
    assert [e.code for e in result.errors] == ["bad-value"]


def test_the_commanded_pointing_reaches_the_renderer_and_the_flight_vo() -> None:
    session = RoverSession("gusev", 5, START, visual_odometry=SeeingVO)
    pairs = _watch_pairs(session)
    c = cmd.DriveStraight(distance_m=0.7, vo=True, vo_az_deg=-30.0, vo_el_deg=-45.0)
    assert session.execute(c).status == "completed"
    az, el = math.radians(-30.0), math.radians(-45.0)
    vo = session.vo
    assert isinstance(vo, SeeingVO)
    assert [(a, e) for _, a, e in vo.seen] == [(az, el)] * 2  # the flight VO: as commanded
    bias = session.sim.mast_bias_rad  # the renderer: as commanded, plus the mast's own bias
    for pair in pairs:
        assert pair.az_rad == pytest.approx(az + bias[0], abs=1e-12)
        assert pair.el_rad == pytest.approx(el + bias[1], abs=1e-12)
        assert pair.rig == VO_RIG


def test_left_out_the_pointing_is_mers_and_one_argument_keeps_the_other() -> None:
    session = RoverSession("gusev", 5, START, visual_odometry=SeeingVO)
    session.execute(cmd.DriveStraight(distance_m=0.7, vo=True))
    session.execute(cmd.TurnInPlace(angle_deg=10.0, vo=True, vo_az_deg=45.0))
    vo = session.vo
    assert isinstance(vo, SeeingVO)
    pointings = [(a, e) for _, a, e in vo.seen]
    assert pointings[:2] == [(VO_MAST_AZ_RAD, VO_MAST_EL_RAD)] * 2  # exactly today's
    assert pointings[2:] == [(math.radians(45.0), VO_MAST_EL_RAD)] * 2


@pytest.mark.parametrize(
    "kwargs,match",
    [
        ({"vo_az_deg": 10.0}, "vo_az_deg: needs vo=on"),
        ({"vo_el_deg": -40.0, "vo": False}, "vo_el_deg: needs vo=on"),
        ({"vo": True, "vo_az_deg": 180.5}, r"vo_az_deg: must be in \[-180, 180\] deg"),
        ({"vo": True, "vo_el_deg": -90.01}, r"vo_el_deg: must be in \[-90, 90\] deg"),
        ({"vo": True, "vo_el_deg": math.nan}, "vo_el_deg: must be in"),
    ],
)
def test_a_pointing_out_of_reach_or_without_vo_is_refused(
    kwargs: dict[str, Any], match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        cmd.DriveArc(radius_m=3.0, angle_deg=10.0, **kwargs)


def test_the_sequence_language_takes_the_pointing() -> None:
    text = (
        "DRIVE_STRAIGHT distance_m=3 vo=on vo_az_deg=-30 vo_el_deg=-40\n"
        "DRIVE_TO x_m=2 y_m=1 vo=on vo_el_deg=-90\n"
        "TURN_IN_PLACE angle_deg=20 vo_az_deg=5\n"
    )
    result = validate(text)
    assert [(e.line, e.code) for e in result.errors] == [(3, "bad-value")]
    assert "vo_az_deg: needs vo=on" in result.errors[0].message
