"""Images in the loop (``sim.loop.imaging``): NAVCAM_STEREO takes a pair at the session's VO
rig size where the mast points, and a ``vo=on vo_keep_images=on`` drive keeps every pair it
takes with what the step saw. Each record carries the rover's estimate as its downlink
reports it, the images in 8 bits as the renderer's DN companded, and nothing of the truth."""

from __future__ import annotations

from datetime import UTC, datetime

import numpy as np
import pytest

from estimation.vo.stereo_rig import NAVCAM
from sequences import commands as cmd
from sim.loop.session import RoverSession

START = datetime(2004, 1, 20, 12, 0, tzinfo=UTC)


@pytest.fixture(scope="module")
def session() -> RoverSession:
    return RoverSession("gusev", 3, START, frame_every_s=1.0)


def test_navcam_stereo_takes_a_pair_at_the_vo_rig_size_where_the_mast_points(
    session: RoverSession,
) -> None:
    before = session.sim.t_s
    report = session.execute(cmd.NavcamStereo(az_deg=20.0, el_deg=-30.0))
    assert report.status == "completed", report.reason
    (image,) = session.take_images()
    assert session.take_images() == []  # handed over once
    assert image["kind"] == "navcam_stereo" and image["vo"] is None
    assert (image["width_px"], image["height_px"]) == (256, 256)  # the session's rig
    assert image["f_px"] == pytest.approx(session.vo.rig.camera.f_px)
    assert image["f_px"] == pytest.approx(NAVCAM.at_resolution(256).camera.f_px)
    assert (image["mast_az_deg"], image["mast_el_deg"]) == pytest.approx((20.0, -30.0))
    # taken when the command started; the command's last frame comes after it
    assert image["t_s"] == pytest.approx(before)
    last = session.take_frames()[-1][0]
    assert last["t_s"] >= image["t_s"] + 19.9
    # the estimate the downlink reports (the rover stood still), not the truth
    assert image["p_mission_est"] == pytest.approx(last["p_mission_est"], abs=1e-12)
    assert image["q_b_ll_est"] == pytest.approx(last["q_b_ll_est"], abs=1e-12)
    assert not any(k.endswith("_true") for k in image)
    left = image["left"]
    assert left.dtype == np.uint8 and left.shape == (256, 256)
    assert 20 < float(left.mean()) < 235 and float(left.std()) > 5.0  # terrain, not blank


def test_a_vo_drive_keeps_every_pair_with_its_features_and_inliers(
    session: RoverSession,
) -> None:
    report = session.execute(cmd.DriveStraight(1.5, vo=True, vo_keep_images=True))
    assert report.status == "completed", report.reason
    images = session.take_images()
    frames = [d for d, _ in session.take_frames()]
    steps = report.details["vo_steps"]
    vos = [i["vo"] for i in images]
    assert all(v is not None for v in vos) and all(i["kind"] == "vo_pair" for i in images)
    assert [v["step"] for v in vos if v] == list(range(steps + 1))  # the first and each
    assert all(v["steps"] == steps for v in vos if v)
    assert vos[0] is not None and vos[0]["status"] == "initialised"
    converged = 0
    for image in images:
        vo, features = image["vo"], image["features"]
        assert vo is not None and features is not None
        assert len(features["features_uv_px"]) == vo["n_features"]
        assert len(features["tracked_uv_px"]) == len(features["inlier"]) == vo["n_tracked"]
        assert len(features["tracked_previous_uv_px"]) == vo["n_tracked"]
        assert sum(features["inlier"]) == vo["n_inliers"]
        uv = np.array(features["features_uv_px"])
        assert uv.size and (uv >= -0.5).all() and (uv <= 255.5).all()  # in the image
        if vo["status"] == "converged":
            converged += 1
            # the pose VO measured is the one SAPP adopted: the frame that reports the step
            step = vo["step"]
            frame = next(f for f in frames if any(
                e["text"].startswith(f"VO step {step}/{steps}:") for e in f["events"]))  # fmt: skip
            assert vo["p_mission_vo"] == pytest.approx(frame["p_mission_est"], abs=1e-9)
            # taken before the update: the estimate then was wheel odometry's
            assert image["p_mission_est"] != pytest.approx(vo["p_mission_vo"], abs=1e-6)
    assert converged == report.details["vo_updates"] >= 1


def test_a_drive_without_vo_keep_images_sends_no_images(session: RoverSession) -> None:
    report = session.execute(cmd.DriveStraight(0.5, vo=True))
    assert report.status == "completed"
    assert session.take_images() == []
