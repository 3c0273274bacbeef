"""Fault injection on the simulator's side (sim.faults): the records' validation, the plan's
schedule and checkpoint, each effect on the truth and sensors, and nothing changed without
a fault."""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime

import numpy as np
import pytest

from sequences import commands as cmd
from sim.errors import InputError
from sim.faults.condition import NavcamFailedError
from sim.faults.plan import FaultPlan
from sim.faults.records import (
    KINDS,
    AccelBias,
    GyroBias,
    HgaStuck,
    NavcamFailure,
    PancamDust,
    SandTrap,
    WheelFault,
    fault_from_dict,
)
from sim.loop.session import RoverSession
from sim.sensors.imu import DEG_PER_H_TO_RAD_S, STANDARD_GRAVITY_M_S2
from sim.sensors.pancam import render_sun_image

START = datetime(2004, 4, 14, 16, 0, tzinfo=UTC)  # Gusev: the sun and Earth up


def session() -> RoverSession:
    return RoverSession("gusev", 3, START, frame_every_s=1.0)


def frames_json(s: RoverSession) -> str:
    return json.dumps(s.take_frames(), default=lambda a: np.asarray(a).tolist())


@pytest.mark.parametrize(
    ("data", "parameter"),
    [
        ({"kind": "meteor"}, "kind"),
        ({"kind": "wheel", "wheel": "XX"}, "wheel"),
        ({"kind": "wheel", "wheel": "LF", "mode": "wobble"}, "mode"),
        ({"kind": "gyro_bias", "axis": "w", "bias_deg_per_h": 1.0}, "axis"),
        ({"kind": "gyro_bias", "axis": "x", "bias_deg_per_h": math.nan}, "bias_deg_per_h"),
        ({"kind": "gyro_bias", "axis": "x", "bias_deg_per_h": 1e6}, "bias_deg_per_h"),
        ({"kind": "gyro_bias", "axis": "x"}, "bias_deg_per_h"),
        ({"kind": "accel_bias", "axis": "y", "bias_ug": "lots"}, "bias_ug"),
        ({"kind": "pancam_dust", "tau": -0.1}, "tau"),
        ({"kind": "pancam_dust", "tau": 10.5}, "tau"),
        ({"kind": "sand_trap", "x_m": 1.0, "y_m": 2.0, "radius_m": 0.0}, "radius_m"),
        ({"kind": "navcam", "tau": 1.0}, "tau"),
    ],
)
def test_a_bad_fault_is_refused_naming_its_parameter(data: dict, parameter: str) -> None:
    with pytest.raises(InputError) as refused:
        fault_from_dict(data)
    assert refused.value.parameter == parameter


def test_every_kind_goes_to_plain_data_and_back() -> None:
    faults = [WheelFault("RM", "stall"), GyroBias("z", -5.0), AccelBias("x", 250.0),
              NavcamFailure(), PancamDust(2.5), SandTrap(3.0, -4.0, 1.5), HgaStuck()]  # fmt: skip
    assert sorted(f.kind for f in faults) == sorted(KINDS)
    for fault in faults:
        assert fault_from_dict(json.loads(json.dumps(fault.as_dict()))) == fault


def test_without_faults_the_records_are_byte_identical() -> None:
    plain, planned = session(), session()
    # a fault that never falls due changes nothing, and neither does the plan itself
    planned.faults.add(GyroBias("z", 100.0), at_t_s=planned.sim.t_s + 1e9)
    commands = [cmd.Wait(30.0), cmd.DriveStraight(0.5), cmd.HgaPass(1.0)]
    for c in commands:
        plain.execute(c), planned.execute(c)
    assert frames_json(plain) == frames_json(planned)
    assert not planned.faults.entries()[0].applied


def test_a_gyro_bias_step_reaches_the_imu_and_only_the_truth_record() -> None:
    s = session()
    before = s.sim.imu.gyro_turn_on_bias_rad_s  # the constant part (the rest drifts)
    s.take_frames()
    entry = s.faults.add(GyroBias("y", 10.0), at_t_s=s.sim.t_s)
    s.execute(cmd.Wait(20.0))
    step = s.sim.imu.gyro_turn_on_bias_rad_s - before
    assert step == pytest.approx([0.0, 10.0 * DEG_PER_H_TO_RAD_S, 0.0], abs=1e-15)
    frames = s.take_frames()
    assert not any(e["kind"] == "fault" for d, _ in frames for e in d["events"])
    texts = [e["text"] for _, t in frames for e in t["events"] if e["kind"] == "fault"]
    assert texts == [f"fault #{entry.fault_id} injected: gyro y bias step +10 deg/h"]
    (applied,) = s.faults.entries()
    assert applied.applied_t_s == pytest.approx(entry.at_t_s)


def test_an_accelerometer_bias_step_in_micro_g() -> None:
    s = session()
    before = s.sim.imu.accel_bias_m_s2
    s.faults.add(AccelBias("x", -500.0), at_t_s=s.sim.t_s)
    s.execute(cmd.Wait(1.0))
    assert s.sim.imu.accel_bias_m_s2 - before == pytest.approx(
        [-500e-6 * STANDARD_GRAVITY_M_S2, 0.0, 0.0], abs=1e-12
    )


def test_a_fault_at_a_later_time_waits_for_the_first_command_after_it() -> None:
    s = session()
    at = s.sim.t_s + 100.0
    s.faults.add(NavcamFailure(), at_t_s=at)
    s.execute(cmd.Wait(60.0))
    assert not s.sim.condition.navcam_failed
    s.execute(cmd.Wait(60.0))
    assert not s.sim.condition.navcam_failed  # due during that wait: at the next start
    s.execute(cmd.Wait(1.0))
    assert s.sim.condition.navcam_failed
    assert s.faults.entries()[0].applied_t_s == pytest.approx(at + 20.0)


def test_failed_navcams_fail_every_vo_step_and_the_drive_goes_on() -> None:
    s = session()
    s.faults.add(NavcamFailure(), at_t_s=s.sim.t_s)
    s.execute(cmd.Wait(1.0))
    with pytest.raises(NavcamFailedError):
        s.sim.navcam_pair()
    report = s.execute(cmd.DriveStraight(0.6, vo=True))
    assert report.status in ("completed", "failed")
    vo = [e.text for e in report.events if e.kind == "vo"]
    assert vo and all("no image" in t for t in vo), vo


def test_dust_dims_and_blurs_the_sun_image() -> None:
    sun_b = np.array([1.0, 0.0, -0.5]) / math.sqrt(1.25)
    az, el = 0.0, math.atan2(0.5, 1.0)
    images = {
        tau: render_sun_image(sun_b, az, el, np.random.default_rng(5), dust_slant_tau=tau)
        for tau in (0.0, 1.0, 4.0)
    }
    clear, dusty, storm = images[0.0], images[1.0], images[4.0]
    assert clear.exposure_s == dusty.exposure_s  # the exposure for the clear sun
    assert storm.peak_e < dusty.peak_e < clear.peak_e * math.exp(-1.0) * 1.0001
    lit = [int(np.count_nonzero(i.image > i.image.mean() + 200)) for i in (clear, dusty)]
    assert lit[1] > lit[0]  # the blurred disk covers more pixels
    with pytest.raises(InputError):
        render_sun_image(sun_b, az, el, np.random.default_rng(5), dust_slant_tau=-1.0)


def test_pancam_dust_reaches_the_rovers_sun_images() -> None:
    clear, dusty = session(), session()
    dusty.faults.add(PancamDust(1.0), at_t_s=dusty.sim.t_s)
    clear.execute(cmd.Wait(1.0)), dusty.execute(cmd.Wait(1.0))
    sun_ll = clear.sim.sun_ll()
    az, el = math.atan2(sun_ll[1], sun_ll[0]), math.asin(-sun_ll[2])
    a = clear.sim.pancam_sun_image(az, el)
    b = dusty.sim.pancam_sun_image(az, el)
    assert 0.0 < b.peak_e < a.peak_e * math.exp(-1.0)  # slant path: more than tau


def test_a_stuck_hga_stays_where_it_stuck_while_earth_moves() -> None:
    healthy, stuck = session(), session()
    stuck.faults.add(HgaStuck(), at_t_s=stuck.sim.t_s)
    for s in (healthy, stuck):
        s.execute(cmd.Wait(1.0)), s.execute(cmd.Wait(3600.0))
    a, b = healthy.take_frames(), stuck.take_frames()
    assert [d for d, _ in a] == [d for d, _ in b]  # the rover reports the same
    assert stuck.sim.condition.hga_stuck_rad is not None

    def moved_deg(frames: list) -> float:
        first, last = (np.array(frames[i][1]["hga_boresight_ll_true"]) for i in (0, -1))
        return math.degrees(math.acos(min(1.0, float(first @ last))))

    assert b[0][1]["hga_error_deg"] == pytest.approx(a[0][1]["hga_error_deg"], abs=0.05)
    assert moved_deg(b) < 1e-3  # the rover at rest, its HGA stuck: the beam stays
    assert moved_deg(a) > 5.0  # the healthy HGA follows Earth across an hour of sky


def test_a_sand_trap_and_a_failed_wheel_change_the_world_not_the_downlink() -> None:
    s = session()
    s.faults.add(SandTrap(2.0, 0.0, 1.0), at_t_s=s.sim.t_s)
    s.faults.add(WheelFault("RF", "stall"), at_t_s=s.sim.t_s)
    s.execute(cmd.Wait(1.0))
    origin = s.loop.recorder.scorer.site_origins_true[0]
    assert s.sim.soil_at(origin[0] + 2.0, origin[1]).name == "sand_trap"
    assert s.sim.failed_wheel == "rf"  # the flight software is not told
    report = s.execute(cmd.DriveStraight(distance_m=4.0))
    assert report.details["distance_truth_m"] < 2.0  # bogged down in the trap
    texts = [e["text"] for d, t in s.take_frames() for e in t["events"]]
    assert sum("fault #" in t for t in texts) >= 2


def test_the_plan_and_the_condition_survive_a_checkpoint() -> None:
    s = session()
    s.faults.add(NavcamFailure(), at_t_s=s.sim.t_s)
    s.faults.add(HgaStuck(), at_t_s=s.sim.t_s)
    s.faults.add(GyroBias("x", 1.0), at_t_s=s.sim.t_s + 1e6)
    s.execute(cmd.Wait(1.0))
    assert s.faults.reveal() == 3
    state = json.loads(json.dumps(s.state(), default=lambda a: np.asarray(a).tolist()))
    again = session()
    again.load_state(state)
    assert again.faults.entries() == s.faults.entries()
    assert again.sim.condition == s.sim.condition
    old = {k: v for k, v in state.items() if k != "faults"}  # a checkpoint from before faults
    old["sim"] = {k: v for k, v in state["sim"].items() if k != "condition"}
    fresh = session()
    fresh.load_state(old)
    assert fresh.faults.entries() == [] and fresh.sim.condition.healthy


def test_a_plan_refuses_a_time_that_is_not_finite() -> None:
    with pytest.raises(InputError, match="at_t_s"):
        FaultPlan().add(NavcamFailure(), math.inf)


def test_thick_dust_makes_sunfind_fail_where_the_clear_sky_finds_the_sun() -> None:
    noon = datetime(2004, 4, 14, 19, 0, tzinfo=UTC)  # Gusev, about 12:30 LMST
    found = {}
    for tau in (0.0, 4.0):
        s = RoverSession("gusev", 3, noon, frame_every_s=1.0)
        if tau:
            s.faults.add(PancamDust(tau), at_t_s=s.sim.t_s)
        s.execute(cmd.NadirUpdate())
        found[tau] = s.execute(cmd.Sunfind()).status
    assert found == {0.0: "completed", 4.0: "failed"}
