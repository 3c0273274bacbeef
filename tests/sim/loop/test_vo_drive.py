"""Drives with visual odometry (Cheng, Maimone and Matthies 2005 sec. 4): steps of at most 0.75 m
and 18 deg, the prediction VO is given and the pose it puts back, and a real ``vo=on`` drive in a
rover session: every step ends in an update or a logged failure, the rover stands while VO
computes, and the attitude changes only when ``vo_attitude`` says so."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.vo.odometry import VoMotion
from sequences import commands as cmd
from sequences.validate import estimate_duration_s, validate
from sim.loop.session import RoverSession
from sim.loop.vo_drive import EstimatedPose, corrected_pose, predicted_motion, split_drive

START = datetime(2004, 4, 14, 15, 0, tzinfo=UTC)


@pytest.mark.parametrize(
    "kind,args",
    [
        ("straight", (0.75,)),
        ("straight", (0.76,)),
        ("straight", (10.0,)),
        ("arc", (-2.0, math.radians(90.0))),
        ("arc", (20.0, math.radians(5.0))),
        ("turn", (math.radians(-181.0),)),
    ],
)
def test_steps_are_short_enough_and_add_up(kind: str, args: tuple[float, ...]) -> None:
    steps = split_drive(kind, args)
    assert all(s == steps[0] for s in steps)
    if kind == "straight":
        assert steps[0][0] <= 0.75 + 1e-12
        assert len(steps) * steps[0][0] == pytest.approx(args[0])
    elif kind == "arc":
        radius, angle = steps[0]
        assert radius == args[0]
        assert abs(radius) * angle <= 0.75 + 1e-12 and angle <= math.radians(18.0) + 1e-12
        assert len(steps) * angle == pytest.approx(args[1])
    else:
        assert abs(steps[0][0]) <= math.radians(18.0) + 1e-12
        assert len(steps) * steps[0][0] == pytest.approx(args[0])
    # as few steps as the limits allow
    assert len(split_drive(kind, args)) == cmd.vo_step_count(
        *(
            (args[0], 0.0)
            if kind == "straight"
            else (abs(args[0]) * args[1], math.degrees(args[1]))
            if kind == "arc"
            else (0.0, math.degrees(args[0]))
        )
    )


def test_the_prediction_put_back_is_the_pose_it_came_from() -> None:
    rng = np.random.default_rng(3)
    q0, q1 = Rotation.random(2, random_state=rng).as_quat()
    before = EstimatedPose(rng.normal(size=3), q0)
    after = EstimatedPose(rng.normal(size=3), q1)
    R_b0_b1, p_b1_b0 = predicted_motion(before, after)
    p_s, q_b_ll = corrected_pose(before, VoMotion(R_b0_b1, p_b1_b0, np.eye(6)))
    np.testing.assert_allclose(p_s, after.p_s, atol=1e-12)
    assert abs(float(np.dot(q_b_ll, q1))) == pytest.approx(1.0, abs=1e-12)
    # the new origin in the old body frame: body x forward, so 1 m ahead is (1, 0, 0)
    ahead = EstimatedPose(before.p_s + before.R_s_b @ [1.0, 0.0, 0.0], q0)
    np.testing.assert_allclose(predicted_motion(before, ahead)[1], [1.0, 0.0, 0.0], atol=1e-12)


def test_vo_attitude_needs_vo() -> None:
    with pytest.raises(ValueError, match="vo_attitude: needs vo=on"):
        cmd.DriveArc(radius_m=3.0, angle_deg=10.0, vo_attitude=True)


def test_the_validator_counts_the_steps_processing_time() -> None:
    plain = estimate_duration_s(cmd.TurnInPlace(angle_deg=-40.0))
    with_vo = estimate_duration_s(cmd.TurnInPlace(angle_deg=-40.0, vo=True))
    assert with_vo - plain == pytest.approx(3 * cmd.VO_PROCESSING_S)


@pytest.mark.parametrize("attitude", [False, True])
def test_a_vo_drive_steps_images_and_updates(attitude: bool) -> None:
    session = RoverSession("gusev", 5, START)
    t0 = session.sim.t_s
    report = session.execute(cmd.DriveStraight(distance_m=1.5, vo=True, vo_attitude=attitude))
    assert report.status == "completed", report.reason
    details = report.details
    assert details["vo_steps"] == 2
    assert details["vo_updates"] + details["vo_failures"] == 2
    vo_events = [e.text for e in report.events if e.kind == "vo"]
    assert all(e.startswith("VO step") for e in vo_events)
    assert len(vo_events) == 2
    assert sum("failed" in e for e in vo_events) == details["vo_failures"]
    assert details["distance_truth_m"] == pytest.approx(1.5, rel=0.1)
    assert session.sim.t_s - t0 >= 2 * cmd.VO_PROCESSING_S + 1.5 / 0.0375
    assert session.nate.aqf.paper_name == "Unknown"  # VO never raises the flag


def test_without_vo_attitude_the_attitude_is_sapps_own() -> None:
    plain, with_vo = (RoverSession("gusev", 5, START) for _ in range(2))
    plain.execute(cmd.DriveStraight(distance_m=0.7))
    report = with_vo.execute(cmd.DriveStraight(distance_m=0.7, vo=True))
    assert report.details["vo_steps"] == 1
    # the same wheels and gyros: the same attitude, whatever VO said about the position
    assert abs(float(np.dot(plain.nate.q_b_ll, with_vo.nate.q_b_ll))) == pytest.approx(1.0)


def test_standing_for_vo_does_not_count_towards_fine_expiring() -> None:
    from tests.sequences.test_sequences import _context

    # 10 drives of 1.5 m with VO: 400 s of driving, 3000 s standing: Fine all the way
    text = "SUNCHECK_SUNGAZE\n" + "DRIVE_STRAIGHT distance_m=1.5 vo=on\n" * 10
    assert [w.code for w in validate(text, _context()).warnings] == []
    # 25 such drives: 1000 s of driving expires Fine (after 900 s), in the 23rd drive
    text = "SUNCHECK_SUNGAZE\n" + "DRIVE_STRAIGHT distance_m=1.5 vo=on\n" * 25
    warnings = validate(text, _context()).warnings
    assert [(w.line, w.code) for w in warnings] == [
        (24, "fine-expires"),
        (25, "drive-not-fine"),  # the two drives after it start Coarse
        (26, "drive-not-fine"),
    ]
