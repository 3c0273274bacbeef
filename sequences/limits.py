"""Limits the ground and the simulator share, in one place.

The flight software's own numbers (NATE's parameters and defaults, the rover's dimensions
and drive rates) live in ``estimation`` and the ground reads them from there. What is here
belongs to no flight module: the bounds of one drive command, and how a ``vo=on`` drive is
cut into visual odometry steps. The command dictionary (``sequences.commands``) refuses what
lies outside them, and the simulator (``sim.rover.drive``, ``sim.loop``) is built on the same
objects, so the two cannot drift apart again.
"""

from __future__ import annotations

MAX_DRIVE_M = 100.0
"""The longest path of one drive command (a straight, an arc, a DRIVE_TO), metres. Ali et
al. 2005 sec. 1 states MER's position requirement for a drive of up to 100 m (10 % of the
distance); at the 3.75 cm/s of sec. 2.5 it is 44 minutes of driving, longer than a single
MER drive primitive ran. The simulator refuses a longer primitive with the same number."""

VO_STEP_MAX_M = 0.75  # Cheng, Maimone and Matthies 2005 sec. 4: at most 75 cm per step
VO_STEP_MAX_DEG = 18.0  # and at most 18 deg of turn, for 60 % overlap between pairs
VO_PROCESSING_S = 150.0  # onboard time per VO step, the rover standing (MER: 2-3 min)

# Visual odometry's Navcam pairs (``sequences.commands``' ``vo_az_deg``, ``vo_el_deg`` and
# ``SET_PARAM param=vo.rig``; the simulator's ``sim.loop.vo_drive``).
VO_MAST_AZ_DEG = 0.0  # omitted: straight ahead ...
VO_MAST_EL_DEG = -35.0  # ... and 35 deg down: the ground ahead, where MER's VO looked
VO_MAST_AZ_RANGE_DEG = (-180.0, 180.0)  # the mast turns the Navcams all the way round
VO_MAST_EL_RANGE_DEG = (-90.0, 90.0)  # from straight down to straight up
VO_RIGS_PX = (256, 1024)  # a VO pair's width and height: MER's downsampled 256 or the full 1024
