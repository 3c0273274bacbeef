"""Images in the loop: NAVCAM_STEREO's handler, and the VO pairs a ``vo_keep_images=on`` drive
keeps (``sim.loop.drives``). Each becomes an image product (``sim.loop.images``) in the
recorder's ``images``, handed on by the session beside its frames (``RoverSession.take_images``)
and sent down like them (``server.comm``).

A pair is rendered at the session's VO rig (``ctx.vo.rig``: 256 x 256 by default, as MER's
VO pairs were, Cheng, Maimone and Matthies 2005 sec. 4), and its record carries the rover's
estimate when it was taken, never the renderer's truth.
"""

from __future__ import annotations

import math
from typing import Any

from estimation.vo.odometry import VoResult
from sequences.imaging import NAVCAM_STEREO_S, NavcamStereo
from sim.loop.context import CommandRefusedError, LoopContext
from sim.loop.images import ImageDict, ImageKind, features_dict, image_record, vo_step_dict
from sim.loop.vo_drive import EstimatedPose, corrected_pose
from sim.sensors.navcam.camera import NavcamPair


def take_image(
    ctx: LoopContext,
    pair: NavcamPair,
    kind: ImageKind,
    az_rad: float,
    el_rad: float,
    vo: tuple[VoResult, int, int, EstimatedPose] | None = None,
) -> ImageDict:
    """Keep ``pair`` (taken now with the mast commanded to ``az_rad``, ``el_rad``) as an
    image product; ``vo``: the VO step's result, step, steps and the pose before it."""
    nate = ctx.nate
    p_mission, q_b_ll = ctx.mission_estimate()
    step = None
    features = None
    if vo is not None:
        result, i, n, before = vo
        measured = None
        if result.converged and result.motion is not None:
            p_s1, q1 = corrected_pose(before, result.motion)
            measured = (nate.sites.to_mission(p_s1, nate.sites.current.index), q1)
        step = vo_step_dict(result, i, n, measured)
        features = features_dict(result.features)
    record = image_record(
        t_s=nate.t_s,
        kind=kind,
        left_dn=pair.left,
        right_dn=pair.right,
        f_px=pair.rig.camera.f_px,
        baseline_m=pair.rig.baseline_m,
        mast_az_rad=az_rad,
        mast_el_rad=el_rad,
        site_index=nate.sites.current.index,
        p_s_est=nate.p_s,
        p_mission_est=p_mission,
        q_b_ll_est=q_b_ll,
        vo=step,
        features=features,
    )
    ctx.recorder.images.append(record)
    return record


def navcam_stereo(ctx: LoopContext, c: NavcamStereo) -> dict[str, Any]:
    """NAVCAM_STEREO: a pair at the VO rig's size where the mast points, sent down; the
    rover stands ``NAVCAM_STEREO_S`` (slew, exposures, read-out). Refused while a NATE camera
    mode has the mast, and with the Navcams failed (``NavcamFailedError``)."""
    if ctx.nate.busy:
        raise CommandRefusedError(f"NAVCAM_STEREO: refused while {ctx.nate.mode.value} runs")
    az, el = math.radians(c.az_deg), math.radians(c.el_deg)
    pair = ctx.sim.navcam_pair(az, el, rig=ctx.vo.rig)
    record = take_image(ctx, pair, "navcam_stereo", az, el)
    ctx.wait(NAVCAM_STEREO_S)  # its last frame is after the pair: they are played out together
    return {"width_px": record["width_px"]}
