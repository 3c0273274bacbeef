"""Drives with visual odometry: MER's step-and-image drive (Cheng, Maimone and Matthies
2005, sec. 4), the geometry between SAPP's estimate and the VO front.

A ``vo=on`` drive is split into steps of at most ``VO_STEP_MAX_M`` of path and
``VO_STEP_MAX_DEG`` of turn (``sequences.commands.vo_step_count``), so that adjacent Navcam
pairs overlap by at least 60 %. A pair is taken before the first step and after each; the
flight software's VO (``estimation.vo.odometry``) is given the motion SAPP propagated over
the step (wheel odometry and gyros) as its prediction, and when it converges SAPP's
position (and attitude, with ``vo_attitude=on``) is replaced by the pose before the step
moved by the motion VO measured. A failed step keeps the wheel-odometry estimate.

Frames: ``b0``/``b1`` the body at the previous and the new pair; ``s`` the current Site
(LL's orientation: NATE's ``q_b_ll`` is ``q_b_s`` here). VO images are MER's: Navcam pairs
at 256 x 256 (``VO_RIG``), the mast looking ahead and 35 deg down, unless the session's VO
rig is 1024 px (``vo_rig``, ``SET_PARAM param=vo.rig``) or the drive points the mast
(``vo_az_deg``, ``vo_el_deg``: ``vo_pointing``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from estimation.vo.odometry import VoMotion
from estimation.vo.stereo_rig import NAVCAM, StereoRig
from sequences import commands as cmd
from sequences.limits import VO_MAST_AZ_DEG, VO_MAST_EL_DEG
from sim.errors import InputError

FloatArray = NDArray[np.float64]

VO_RIG = NAVCAM.at_resolution(256)  # MER downsampled its Navcam pairs for VO (sec. 4)
VO_MAST_AZ_RAD = math.radians(VO_MAST_AZ_DEG)  # straight ahead
# the ground ahead (sim.sensors.navcam.camera.DEFAULT_EL_RAD)
VO_MAST_EL_RAD = math.radians(VO_MAST_EL_DEG)
# The rigs a session's VO may image through, by width (sequences.limits.VO_RIGS_PX): MER's
# downsampled pairs and the full Navcam frame.
VO_RIGS: dict[int, StereoRig] = {256: VO_RIG, 1024: NAVCAM.at_resolution(1024)}


def vo_rig(width_px: object) -> StereoRig:
    """The VO rig ``width_px`` wide (256 or 1024); ``InputError`` naming ``vo_rig`` else.

    >>> vo_rig(1024).camera.width_px
    1024
    """
    for width, rig in VO_RIGS.items():
        if width_px == width and not isinstance(width_px, bool):
            return rig
    rigs = " or ".join(str(w) for w in VO_RIGS)
    raise InputError("vo_rig", f"must be {rigs} (px), got {width_px!r}")


def vo_pointing(command: cmd.Command) -> tuple[float, float]:
    """The mast ``(az_rad, el_rad)`` of a drive's VO pairs: its ``vo_az_deg``,
    ``vo_el_deg``, each omitted one MER's (``VO_MAST_AZ_RAD``, ``VO_MAST_EL_RAD``).

    >>> vo_pointing(cmd.DriveStraight(distance_m=1.0, vo=True)) == (VO_MAST_AZ_RAD, VO_MAST_EL_RAD)
    True
    >>> [round(math.degrees(a), 9) for a in vo_pointing(
    ...     cmd.DriveStraight(distance_m=1.0, vo=True, vo_az_deg=-40.0))]
    [-40.0, -35.0]
    """
    az_deg = getattr(command, "vo_az_deg", None)
    el_deg = getattr(command, "vo_el_deg", None)
    az = VO_MAST_AZ_RAD if az_deg is None else math.radians(float(az_deg))
    el = VO_MAST_EL_RAD if el_deg is None else math.radians(float(el_deg))
    return az, el


@dataclass(frozen=True)
class VoDriveOptions:
    """How a session steps and images its ``vo=on`` drives. ``step_max_m``,
    ``step_max_deg``: the longest step and the largest turn per step (MER's 0.75 m and
    18 deg, Cheng, Maimone and Matthies 2005 sec. 4; the seed's ground test drove 35 cm steps, sec.
    3); ``rover_shadow``: draw the rover's own shadow in the VO pairs (sec. 4.3's false
    positive; ``sim.sensors.navcam.camera``)."""

    step_max_m: float = cmd.VO_STEP_MAX_M
    step_max_deg: float = cmd.VO_STEP_MAX_DEG
    rover_shadow: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.step_max_m) and 0.0 < self.step_max_m <= cmd.VO_STEP_MAX_M):
            raise InputError("step_max_m", f"must be in (0, {cmd.VO_STEP_MAX_M:g}] m")
        if not (math.isfinite(self.step_max_deg) and 0.0 < self.step_max_deg <= 90.0):
            raise InputError("step_max_deg", "must be in (0, 90] deg")
        if not isinstance(self.rover_shadow, bool):
            raise InputError("rover_shadow", f"must be a bool, got {self.rover_shadow!r}")


def split_drive(
    kind: str, args: tuple[float, ...], options: VoDriveOptions | None = None
) -> list[tuple[float, ...]]:
    """The steps of a ``vo=on`` drive: ``kind`` ``straight`` (distance_m,), ``arc``
    (radius_m, angle_rad) or ``turn`` (angle_rad,), each step the same kind, within
    ``options``' step limits (MER's by default).

    >>> split_drive("straight", (2.0,))
    [(0.6666666666666666,), (0.6666666666666666,), (0.6666666666666666,)]
    >>> [round(math.degrees(a), 6) for (a,) in split_drive("turn", (math.radians(-40.0),))]
    [-13.333333, -13.333333, -13.333333]
    >>> len(split_drive("straight", (2.45,), VoDriveOptions(step_max_m=0.35)))
    7
    """
    o = options if options is not None else VoDriveOptions()
    limits = (o.step_max_m, o.step_max_deg)
    if kind == "straight":
        (distance,) = args
        n = cmd.vo_step_count(distance, 0.0, *limits)
        return [(distance / n,)] * n
    if kind == "arc":
        radius, angle = args
        n = cmd.vo_step_count(abs(radius) * angle, math.degrees(angle), *limits)
        return [(radius, angle / n)] * n
    if kind == "turn":
        (angle,) = args
        n = cmd.vo_step_count(0.0, math.degrees(angle), *limits)
        return [(angle / n,)] * n
    raise ValueError(f"kind: must be straight, arc or turn, got {kind!r}")


@dataclass(frozen=True)
class EstimatedPose:
    """SAPP's estimate at a pair: position in the Site (m) and ``q_b_ll`` (= ``q_b_s``)."""

    p_s: FloatArray
    q_b_ll: FloatArray

    @property
    def R_s_b(self) -> FloatArray:
        out: FloatArray = Rotation.from_quat(self.q_b_ll).inv().as_matrix()
        return out


def predicted_motion(before: EstimatedPose, after: EstimatedPose) -> tuple[FloatArray, FloatArray]:
    """The motion SAPP propagated between two pairs, as VO wants its prediction:
    ``R_b0_b1`` and ``p_b1_b0`` (the new body origin in the previous body frame)."""
    R_s_b0, R_s_b1 = before.R_s_b, after.R_s_b
    return R_s_b0.T @ R_s_b1, R_s_b0.T @ (after.p_s - before.p_s)


def corrected_pose(before: EstimatedPose, motion: VoMotion) -> tuple[FloatArray, FloatArray]:
    """The pose VO measured: ``p_s`` and ``q_b_ll`` after ``motion`` from ``before``."""
    R_s_b0 = before.R_s_b
    p_s1 = before.p_s + R_s_b0 @ motion.p_b1_b0
    q_b_ll1 = Rotation.from_matrix(R_s_b0 @ motion.R_b0_b1).inv().as_quat()
    return p_s1, q_b_ll1


def update_text(step: int, steps: int, shift_s: ArrayLike, inliers: int, tracked: int) -> str:
    """The event of an accepted VO update."""
    d = np.asarray(shift_s, dtype=float)
    return (
        f"VO step {step}/{steps}: position moved ({d[0]:+.3f}, {d[1]:+.3f}, {d[2]:+.3f}) m "
        f"from wheel odometry, {inliers} of {tracked} features"
    )
