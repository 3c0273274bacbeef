"""One home for every shared number: the ground reads the flight software's, and the ground
and the simulator share ``sequences.limits``. The drive limit had drifted (the dictionary
said 100 m "as the simulator", which allowed 1000 m): both now hold the same object, and a
drive just over it is refused by both."""

from __future__ import annotations

import math

import pytest

from estimation import geometry
from estimation.sapp.nadir import NadirParams
from estimation.sapp.nate import NateParams
from estimation.sapp.nate_io import FINE_TO_COARSE_S
from estimation.sapp.sun_modes import SungazeParams
from sequences import commands as cmd
from sequences import limits, validate
from sim.errors import InputError
from sim.loop import vo_drive
from sim.rover import drive
from sim.rover.slip import SlipModel
from sim.world.terrain import FlatTerrain

JUST_OVER_M = limits.MAX_DRIVE_M + 0.01


def test_the_drive_limit_is_one_number_for_the_dictionary_and_the_simulator() -> None:
    assert limits.MAX_DRIVE_M == 100.0
    assert cmd.MAX_DRIVE_M is limits.MAX_DRIVE_M
    assert drive.MAX_PATH_M is limits.MAX_DRIVE_M


def test_a_straight_drive_just_over_the_limit_is_refused_by_both() -> None:
    cmd.DriveStraight(distance_m=limits.MAX_DRIVE_M)  # at the limit: accepted
    with pytest.raises(ValueError, match="distance_m"):
        cmd.DriveStraight(distance_m=JUST_OVER_M)
    result = validate.validate(f"DRIVE_STRAIGHT distance_m={JUST_OVER_M}")
    assert [d.code for d in result.errors] == ["bad-value"]
    flat = FlatTerrain()
    with pytest.raises(InputError, match="distance_m"):
        drive.drive_straight(
            flat, drive.initial_state(flat, 0.0), JUST_OVER_M, SlipModel.ideal(flat.soil)
        )


def test_an_arc_just_over_the_limit_is_refused_by_both() -> None:
    radius_m = 20.0
    angle_deg = math.degrees(JUST_OVER_M / radius_m)
    with pytest.raises(ValueError, match="angle_deg"):
        cmd.DriveArc(radius_m=radius_m, angle_deg=angle_deg)
    flat = FlatTerrain()
    with pytest.raises(InputError, match="angle_rad"):
        drive.drive_arc(
            flat,
            drive.initial_state(flat, 0.0),
            radius_m,
            math.radians(angle_deg),
            SlipModel.ideal(flat.soil),
        )


def test_the_vo_step_limits_are_shared_with_the_simulator() -> None:
    assert cmd.VO_STEP_MAX_M is limits.VO_STEP_MAX_M
    assert cmd.VO_STEP_MAX_DEG is limits.VO_STEP_MAX_DEG
    assert cmd.VO_PROCESSING_S is limits.VO_PROCESSING_S
    assert vo_drive.VoDriveOptions().step_max_m == limits.VO_STEP_MAX_M


def test_the_ground_reads_the_flight_softwares_numbers() -> None:
    assert validate.DRIVE_SPEED_M_S is geometry.DRIVE_SPEED_M_S
    assert validate.TURN_RATE_DEG_S is geometry.TURN_RATE_DEG_S
    assert drive.DEFAULT_SPEED_M_S is geometry.DRIVE_SPEED_M_S
    assert drive.DEFAULT_TURN_RATE_RAD_S is geometry.TURN_RATE_RAD_S
    assert NadirParams().window_s == validate.NADIR_WINDOW_S
    assert SungazeParams().timer_s == validate.SUNGAZE_S
    assert NateParams().gyrocompass_duration_s == validate.GYROCOMPASS_S
    assert validate.FINE_TO_COARSE_S == NateParams().fine_to_coarse_s == FINE_TO_COARSE_S
    assert cmd.MIN_ARC_RADIUS_M == 0.5 * geometry.FLIGHT_GEOMETRY.track_m == 0.6


def test_every_command_has_one_duration_row() -> None:
    assert set(validate._DURATION_S) == set(cmd.COMMANDS.values())
