"""Visual odometry's settings in the command dictionary (``sequences.commands``): where the
Navcams look for a drive's VO pairs, and the rover's VO settings that SET_PARAM changes.

A ``vo=on`` drive takes ``vo_az_deg`` and ``vo_el_deg``: the mast pointing of its pairs in
the body frame (azimuth clockwise from the rover's forward seen from above, elevation up
from the deck plane: ``estimation.camera_model.R_b_pancam``), MER's straight ahead and
35 deg down when omitted: VO "requires active pointing by human drivers in feature-poor
terrain" (Cheng, Maimone and Matthies 2005 sec. 5).
``SET_PARAM param=vo.rig value=1024`` makes the pairs 1024 x 1024 (MER's full Navcam
frame) instead of the 256 x 256 MER downsampled to (sec. 4); the simulator keeps the
setting as session state (``sim.loop.session``).
"""

from __future__ import annotations

from collections.abc import Mapping

from sequences.command_base import ArgSpec, Command, shown
from sequences.limits import (
    VO_MAST_AZ_DEG,
    VO_MAST_AZ_RANGE_DEG,
    VO_MAST_EL_DEG,
    VO_MAST_EL_RANGE_DEG,
    VO_RIGS_PX,
)

# The Navcams' pointing for a drive's VO pairs (body frame, as the mast points them:
# ``estimation.camera_model.R_b_pancam``); omitted, MER's.
VO_POINTING_SPECS: Mapping[str, ArgSpec] = {
    "vo_az_deg": ArgSpec(
        "number",
        "deg",
        *VO_MAST_AZ_RANGE_DEG,
        note=f"with vo=on: the mast azimuth of the VO pairs, clockwise from the rover's "
        f"forward seen from above; omit: {VO_MAST_AZ_DEG:g} (ahead)",
    ),
    "vo_el_deg": ArgSpec(
        "number",
        "deg",
        *VO_MAST_EL_RANGE_DEG,
        note=f"with vo=on: the mast elevation of the VO pairs, up from the rover's deck "
        f"plane; omit: {VO_MAST_EL_DEG:g} (the ground ahead)",
    ),
}


def check_vo_pointing(command: Command) -> None:
    """``ValueError`` naming ``vo_az_deg`` or ``vo_el_deg`` when a drive gives one without
    ``vo=on`` (their ranges are the specs')."""
    for name in VO_POINTING_SPECS:
        if getattr(command, name, None) is not None and not getattr(command, "vo", False):
            raise ValueError(f"{name}: needs vo=on")


def check_vo_setting(param: str, value: float | bool) -> None:
    """``ValueError`` unless ``SET_PARAM param=<param> value=<value>`` is a VO setting the
    rover has: ``vo.rig``, the width of the VO pairs in pixels (``VO_RIGS_PX``).

    >>> check_vo_setting("vo.rig", 1024)
    >>> check_vo_setting("vo.rig", 512)
    Traceback (most recent call last):
    ...
    ValueError: value: vo.rig must be 256 or 1024 (px), got 512
    """
    if param != "vo.rig":
        raise ValueError(f"param: {param}: no such VO setting (here: vo.rig)")
    if isinstance(value, bool) or value not in VO_RIGS_PX:
        rigs = " or ".join(str(w) for w in VO_RIGS_PX)
        raise ValueError(f"value: vo.rig must be {rigs} (px), got {shown(value)}")
