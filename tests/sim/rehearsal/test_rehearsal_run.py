"""One rehearsal run: deterministic, started from the report, the runtime's stop rule."""

from __future__ import annotations

import math

import numpy as np
from rehearsal_data import plane_map, report

from estimation.protection.keepout import KeepOutZone
from sim.rehearsal.inputs import GroundMapData, Priors, RehearsalInputs
from sim.rehearsal.run import Rehearsal, RunSeeds, run_once, thinned_path
from sim.rehearsal.start import heading_of, sample_start

DRIVE = "SEQUENCE t\nDRIVE_STRAIGHT distance_m=1\n"


def test_a_run_is_bit_identical_twice_and_differs_between_runs(
    ground_map: GroundMapData,
) -> None:
    inputs = RehearsalInputs(report(), ground_map, DRIVE)
    a, b = run_once(inputs, 3, 11), run_once(inputs, 3, 11)
    assert a.steps == b.steps and a.extra == b.extra
    c = run_once(inputs, 4, 11)
    assert c.steps[0].p_mission_true_m != a.steps[0].p_mission_true_m
    step = a.steps[0]
    assert step.status == "completed" and step.line == 2
    # it drove about a metre North from its true start, and knows it to a few cm
    start = np.array(a.extra["start_true_m"])
    moved = np.array(step.p_mission_true_m) - start
    assert 0.8 < moved[0] < 1.1 and abs(moved[1]) < 0.1
    assert math.dist(step.p_mission_est_m, step.p_mission_true_m) < 0.2
    assert step.path_true_m[0] == tuple(start) and step.path_true_m[-1] == step.p_mission_true_m
    assert 4 <= len(step.path_true_m) <= 7  # about four points per metre
    assert 0.0 < step.max_tilt_true_deg < 10.0  # a 2 % plane with Gusev's roughness and rocks
    assert math.isnan(step.hga_margin_deg)


def test_a_zero_sigma_start_is_the_estimate() -> None:
    start = report(position_sigma_m=0.0, aqf="Fine")
    true = sample_start(start, Priors(), np.random.default_rng(2))
    assert true.p_mission_m == (0.5, 0.2)
    assert abs(true.yaw_rad - heading_of(start.q_b_ll_est)) < math.radians(0.35 * 5)
    budget = Priors(odometry_error_by_site=())  # the onboard budget: 1σ along the heading
    spread = [
        sample_start(report(position_sigma_m=0.5), budget, np.random.default_rng(s)).p_mission_m
        for s in range(200)
    ]
    assert 0.4 < float(np.std(np.array(spread)[:, 0])) < 0.6
    assert abs(float(np.mean(np.array(spread)[:, 0])) - 0.5) < 0.1


def test_a_site_s_measured_odometry_error_puts_the_start_behind_the_estimate() -> None:
    # heading North: along track is North (x), across is East (y)
    priors = Priors(odometry_error_by_site=(("gusev", -1.5, 0.5, 0.25),))
    starts = np.array([
        sample_start(report(position_sigma_m=0.2), priors, np.random.default_rng(s)).p_mission_m
        for s in range(400)
    ])  # fmt: skip
    along, across = starts[:, 0] - 0.5, starts[:, 1] - 0.2
    assert abs(float(np.mean(along)) - (-1.5 * 0.2)) < 0.015  # 5 standard errors
    assert 0.085 < float(np.std(along)) < 0.115 and 0.04 < float(np.std(across)) < 0.06
    # a scenario place is judged by the site it lies in; a site not listed keeps the budget
    assert priors.odometry_error("gusev") == priors.odometry_error("gusev:anywhere")
    assert priors.odometry_error("meridiani") is None


def test_nate_starts_at_the_report(ground_map: GroundMapData) -> None:
    q = (0.0, 0.0, -math.sin(0.25), math.cos(0.25))  # q_b_ll of a heading of 0.5 rad
    zone = KeepOutZone.circle("rock", 1, 3.0, 1.0, 0.4)
    start = report(
        p_s_est=(1.5, -0.5, 0.0),
        p_mission_est=(4.0, 2.0, 0.0),
        site_index=2,
        q_b_ll_est=q,
        aqf="Coarse",
        imu_integration_s=350.0,
        gyro_counter_s=120.0,
        keepout_zones=(zone,),
        params={"mobility.keepout_k_sigma": 3.0},
    )
    run = Rehearsal(RehearsalInputs(start, ground_map, DRIVE), RunSeeds.of(0, 0))
    nate, protection = run.session.nate, run.session.loop.protection
    assert np.array_equal(nate.p_s, [1.5, -0.5, 0.0])
    assert nate.sites.current.index == 2
    assert np.allclose(nate.sites.to_mission(nate.p_s, 2), [4.0, 2.0, 0.0], atol=1e-12)
    assert nate.aqf.paper_name == "Coarse"
    assert nate.imu_integration_s == 350.0 and nate.gyro_counter_s == 120.0
    assert nate.t_s == start.t_s == run.session.sim.t_s
    assert abs(heading_of(nate.q_b_ll) - 0.5) < 1e-12
    assert protection.zones == {"rock": zone} and protection.limits.keepout_k_sigma == 3.0
    assert protection.uncertainty.sigma_m == 0.05
    # the truth: near the estimate, settled at the reported (level) tilt
    sim = run.session.sim
    assert math.dist(sim.drive_state.p_s[:2], (4.0, 2.0)) < 0.5
    z = sim.drive_state.q_s_b
    tilt = 2.0 * math.degrees(math.asin(math.hypot(z[0], z[1])))
    assert tilt < 1.0


def test_a_refused_step_stops_the_rest() -> None:
    gmap = plane_map()
    text = "SEQUENCE t\nDRIVE_STRAIGHT distance_m=1\nWAIT duration_s=10\n"
    start = report(mobility_fault="slip check: slip 40.0 % over 1.00 m > limit 30 %")
    out = run_once(RehearsalInputs(start, gmap, text), 0, 5)
    assert [s.status for s in out.steps] == ["refused", "not_run"]
    assert "mobility disabled" in (out.steps[0].reason or "")
    assert out.steps[1].line == 3 and math.isnan(out.steps[1].end_t_s)


def test_a_failed_step_does_not_stop_and_time_tags_are_kept() -> None:
    gmap = plane_map()
    text = "SEQUENCE t\nWAIT duration_s=5\n@ +30s WAIT duration_s=5\n"
    out = run_once(RehearsalInputs(report(), gmap, text), 0, 5)
    first, second = out.steps
    assert first.status == second.status == "completed"
    assert second.start_t_s == first.end_t_s + 30.0


def test_a_drive_into_a_keepout_zone_records_it_and_the_halt() -> None:
    """The rover starts inside a zone's edge (a drive there halts as soon as it goes
    deeper) and drives towards its centre: halted by the keep-out check, in the zone."""
    zone = KeepOutZone.circle("rock1", 0, 1.7, 0.2, 1.5)  # 1.2 m ahead, the rover inside
    start = report(position_sigma_m=0.0, keepout_zones=(zone,))
    text = "SEQUENCE t\nDRIVE_STRAIGHT distance_m=2\nWAIT duration_s=10\n"
    out = run_once(RehearsalInputs(start, plane_map(), text), 1, 2)
    drive, wait = out.steps
    assert drive.status == "halted" and drive.reason == "keepout"
    assert drive.keepouts_entered == ("rock1",)
    assert wait.status == "not_run"


def test_thinned_path_keeps_its_ends_and_spacing() -> None:
    p = np.column_stack([np.linspace(0.0, 2.0, 401), np.zeros(401)])
    thin = thinned_path(p)
    assert np.array_equal(thin[0], p[0]) and np.array_equal(thin[-1], p[-1])
    assert np.allclose(np.diff(thin[:-1, 0]), 0.25, atol=0.006)


def test_an_hga_pass_at_an_lmst_tag_gives_its_margins() -> None:
    from sim.world.marsclock import MISSIONS, lmst_h_from_t_s

    text = "SEQUENCE t\n@ 13:00 LMST HGA_PASS duration_min=5\n"
    (step,) = run_once(RehearsalInputs(report(), plane_map(), text), 0, 1).steps
    assert step.status == "completed"
    lmst = float(lmst_h_from_t_s(step.start_t_s, MISSIONS["spirit"].lon_west_deg))
    assert abs(lmst - 13.0) < 1e-6 and step.start_t_s > report().t_s
    assert abs(step.end_t_s - step.start_t_s - 300.0) < 1e-6
    assert 0.0 < step.hga_margin_deg <= 2.0  # a Fine attitude keeps the HGA in its 2 deg beam
    assert 0.0 < step.hga_margin_predicted_deg < step.hga_margin_deg
