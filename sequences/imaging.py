"""The commands and arguments that make images the rover sends down: ``NAVCAM_STEREO`` (a
Navcam stereo pair where the mast points) and the drives' ``vo_keep_images`` (every VO pair
of a ``vo=on`` drive kept, with its tracked features and inliers).

The mast's reach is MER's Pancam Mast Assembly's: the Navcams turn 360 deg in azimuth and
+-90 deg in elevation (Maki et al. 2003). A pair is taken at the session's VO rig size (MER
downsampled its Navcam pairs to 256 x 256 for VO, Cheng, Maimone and Matthies 2005 sec. 4).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import ClassVar

from sequences.command_base import ArgSpec, Command

MAST_AZ_MIN_DEG, MAST_AZ_MAX_DEG = -180.0, 180.0  # 360 deg of azimuth (Maki et al. 2003)
MAST_EL_MIN_DEG, MAST_EL_MAX_DEG = -90.0, 90.0  # +-90 deg of elevation
NAVCAM_STEREO_S = 20.0  # slew, expose and read out both Navcams, the rover standing

KEEP_IMAGES_SPECS: Mapping[str, ArgSpec] = {
    "vo_keep_images": ArgSpec(
        "boolean",
        note="with vo=on: every VO pair is kept and sent down with its tracked features and "
        "inliers (images at the VO rig's size, priority of the decimated telemetry)",
    ),
}


def check_keep_images(command: Command) -> None:
    """``vo_keep_images`` needs ``vo=on``."""
    if getattr(command, "vo_keep_images", False) and not getattr(command, "vo", False):
        raise ValueError("vo_keep_images: needs vo=on")


@dataclass(frozen=True)
class NavcamStereo(Command):
    """Take a Navcam stereo pair with the mast at ``az_deg`` (clockwise from the rover's
    forward axis, seen from above) and ``el_deg`` (> 0 above the horizon of the deck), at
    the VO rig's size; the pair is sent down (``sim.loop.imaging``)."""

    name: ClassVar[str] = "NAVCAM_STEREO"
    in_articulate: ClassVar[bool] = True  # the rover stands: Articulate propagates on
    specs: ClassVar[Mapping[str, ArgSpec]] = {
        "az_deg": ArgSpec(
            "number",
            "deg",
            MAST_AZ_MIN_DEG,
            MAST_AZ_MAX_DEG,
            note="clockwise from the rover's forward axis; 0: straight ahead",
        ),
        "el_deg": ArgSpec(
            "number",
            "deg",
            MAST_EL_MIN_DEG,
            MAST_EL_MAX_DEG,
            note="above the deck's horizon; -35: the ground a few metres ahead (VO's)",
        ),
    }
    az_deg: float
    el_deg: float = -35.0
