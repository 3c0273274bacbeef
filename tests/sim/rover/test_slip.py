"""Slip, creep and sinkage model: the curve against MER's experience and an independent
inversion of the shear law, monotonicity, the no-slip mode, reproducible noise."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from estimation.mars_constants import MARS_GRAVITY_M_S2
from sim.errors import InputError
from sim.rover.geometry import MER_GEOMETRY
from sim.rover.slip import SlipModel, SlipParams, slip_curve, turn_slip_curve
from sim.world.terrain import BEDROCK, GUSEV_SOIL, MERIDIANI_SAND, Soil

DEG = math.pi / 180.0


def test_level_ground_slip_is_a_few_percent() -> None:
    # Ali et al. 2005 section 4: Opportunity on the plains "very small amounts of slip".
    for soil in (GUSEV_SOIL, MERIDIANI_SAND):
        s, c = slip_curve(soil, 0.0)
        assert 0.01 <= float(s) <= 0.06, soil.name
        assert float(c) == 0.0
    s_rock, _ = slip_curve(BEDROCK, 0.0)
    assert float(s_rock) == 0.0  # no sinkage: no compaction resistance to overcome


def test_sand_slopes_match_mer_experience() -> None:
    # MER on loose sand: tens of percent at 15-20°, 100 % and more (sliding back) at 25-30°.
    s, _ = slip_curve(MERIDIANI_SAND, np.array([15.0, 20.0]) * DEG)
    assert np.all((s >= 0.1) & (s <= 0.5))
    s_steep, _ = slip_curve(MERIDIANI_SAND, np.array([25.0, 28.0, 30.0]) * DEG)
    assert np.all(s_steep >= 1.0)
    # Gusev soil is stronger (35° friction, 1 kPa cohesion) than the sand (30°, 0.2 kPa).
    s_gusev, _ = slip_curve(GUSEV_SOIL, 20.0 * DEG)
    assert float(s_gusev) < float(s[1])


def test_slip_grows_with_slope_and_skids_downhill() -> None:
    slopes = np.linspace(-25.0, 25.0, 201) * DEG
    for soil in (GUSEV_SOIL, MERIDIANI_SAND, BEDROCK):
        s, _ = slip_curve(soil, slopes)
        capped = s >= SlipParams().slip_max
        assert np.all(np.diff(s[~capped]) > 0.0), soil.name  # strictly increasing
        assert float(slip_curve(soil, -10.0 * DEG)[0]) < 0.0  # downhill: wheels skid
    # A weaker soil slips more on the same slope.
    weak = Soil("weak", friction_angle_deg=25.0, cohesion_kpa=0.0, sinkage_m=0.01)
    assert float(slip_curve(weak, 10 * DEG)[0]) > float(slip_curve(MERIDIANI_SAND, 10 * DEG)[0])


def test_slip_blows_up_below_the_friction_angle() -> None:
    p = SlipParams()
    for soil in (GUSEV_SOIL, MERIDIANI_SAND):
        phi = soil.friction_angle_deg
        at_limit, _ = slip_curve(soil, phi * DEG)
        assert float(at_limit) == p.slip_max  # sliding back, capped
        ten_below, _ = slip_curve(soil, (phi - 10.0) * DEG)
        assert 0.0 < float(ten_below) < 0.5


def test_slip_inverts_the_janosi_hanamoto_law() -> None:
    # Independent check: solve H_req = H_max (1 - exp(-s L / K)) for s with a root finder,
    # H from Mohr-Coulomb and Bekker as written in the module docstring.
    soil, p, g = MERIDIANI_SAND, SlipParams(), MER_GEOMETRY
    weight = g.mass_kg * MARS_GRAVITY_M_S2
    z0, r = soil.sinkage_m, g.wheel_radius_m
    area = 6.0 * g.wheel_width_m * math.sqrt(2.0 * r * z0)
    for slope_deg in (0.0, 5.0, 12.0, 18.0, 22.0):
        th = slope_deg * DEG
        h_req = weight * (math.sin(th) + 0.75 * math.sqrt(z0 / (2.0 * r)) * math.cos(th))
        h_max = soil.cohesion_kpa * 1e3 * area + weight * math.cos(th) * math.tan(
            soil.friction_angle_deg * DEG
        )

        def residual(s: float, h_max: float = h_max, h_req: float = h_req) -> float:
            return h_max * (1.0 - math.exp(-s / p.shear_ratio)) - h_req

        s_ref = brentq(residual, 0.0, 10.0)
        s, _ = slip_curve(soil, th)
        assert float(s) == pytest.approx(s_ref, abs=1e-9)


def test_creep_runs_downslope_and_grows_with_cross_slope() -> None:
    cross = np.linspace(-20.0, 20.0, 81) * DEG
    _, c = slip_curve(GUSEV_SOIL, 0.0, cross)
    assert np.all(np.sign(c[cross != 0]) == -np.sign(cross[cross != 0]))  # ground rises right
    assert float(c[40]) == 0.0
    assert np.all(np.diff(np.abs(c[41:])) > 0.0)
    # Climbing uses traction, leaving less to hold the cross slope: more creep.
    _, c_climb = slip_curve(GUSEV_SOIL, 15.0 * DEG, 10.0 * DEG)
    _, c_level = slip_curve(GUSEV_SOIL, 0.0, 10.0 * DEG)
    assert abs(float(c_climb)) > abs(float(c_level))


def test_turn_in_place_slips_more_on_slopes() -> None:
    s, c = turn_slip_curve(GUSEV_SOIL, np.array([0.0, 10.0, 20.0]) * DEG)
    assert np.all(np.diff(s) > 0.0) and np.all(np.diff(c) > 0.0)
    assert float(c[0]) == 0.0


def test_sinkage_grows_with_slip_and_sets_the_effective_radius() -> None:
    model = SlipModel(MERIDIANI_SAND, np.random.default_rng(0))
    z = model.sinkage_m(np.array([-0.2, 0.0, 0.5, 1.0]))
    assert z[0] == z[1] == MERIDIANI_SAND.sinkage_m  # static sinkage when not digging
    assert z[3] == pytest.approx(2.0 * MERIDIANI_SAND.sinkage_m)  # doubles at 100 % slip
    assert np.all(np.diff(z[1:]) > 0.0)
    cap = model.params.max_sinkage_fraction * MER_GEOMETRY.wheel_radius_m
    assert float(model.sinkage_m(1e6)) == pytest.approx(cap)


def test_no_slip_mode_is_ideal_rolling() -> None:
    model = SlipModel.ideal(MERIDIANI_SAND)
    noise = model.noise(np.full(10, 0.01))
    assert np.all(noise == 0.0)
    sample = model.drive(np.full(10, 20 * DEG), np.full(10, 10 * DEG), noise)
    assert np.all(sample.slip == 0.0) and np.all(sample.creep == 0.0)
    assert np.all(sample.sinkage_m == 0.0)
    turn = model.turn(np.full(10, 20 * DEG), noise)
    assert np.all(turn.slip == 0.0) and np.all(turn.creep == 0.0)


def test_same_seed_same_draws_and_split_steps_agree() -> None:
    steps = np.full(400, 0.0047)
    a = SlipModel(GUSEV_SOIL, np.random.default_rng(7)).noise(steps)
    b = SlipModel(GUSEV_SOIL, np.random.default_rng(7)).noise(steps)
    c = SlipModel(GUSEV_SOIL, np.random.default_rng(8)).noise(steps)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)
    split = SlipModel(GUSEV_SOIL, np.random.default_rng(7))
    parts = np.concatenate([split.noise(steps[:150]), split.noise(steps[150:])])
    np.testing.assert_allclose(parts, a, rtol=0.0, atol=1e-15)


def test_gauss_markov_statistics_follow_distance() -> None:
    # Exact discretisation: the variance and the correlation at one correlation length
    # do not depend on the step. 300 correlation lengths of 1 cm steps.
    p = SlipParams()
    model = SlipModel(GUSEV_SOIL, np.random.default_rng(3), params=p)
    step = 0.01
    e = model.noise(np.full(int(300 * p.correlation_length_m / step), step))
    assert np.std(e[:, 0]) == pytest.approx(p.sigma_slip, rel=0.15)
    assert np.std(e[:, 1]) == pytest.approx(p.sigma_creep, rel=0.15)
    lag = round(p.correlation_length_m / step)
    x = e[:, 0] - e[:, 0].mean()
    rho = float(np.dot(x[:-lag], x[lag:]) / np.dot(x, x))
    assert rho == pytest.approx(math.exp(-1.0), abs=0.12)


def test_bad_parameters_are_rejected() -> None:
    with pytest.raises(InputError, match="shear_ratio"):
        SlipParams(shear_ratio=-1.0)
    with pytest.raises(InputError, match="sigma_slip"):
        SlipParams(sigma_slip=float("nan"))
    with pytest.raises(InputError, match="rng"):
        SlipModel(GUSEV_SOIL)
    with pytest.raises(InputError, match="step_distance_m"):
        SlipModel(GUSEV_SOIL, np.random.default_rng(0)).noise([0.1, -0.1])


def test_a_commanded_slip_range_holds_one_draw_per_drive_within_it() -> None:
    params = SlipParams(slip_range=(0.3, 0.6))
    model = SlipModel(GUSEV_SOIL, np.random.default_rng(4), params)
    held = []
    for _ in range(200):  # one draw per drive, held over its steps, whatever the slope
        noise = model.noise(np.full(20, 0.01))
        sample = model.drive(np.linspace(-0.3, 0.3, 20), np.zeros(20), noise)
        assert np.all(sample.slip == sample.slip[0])
        held.append(float(sample.slip[0]))
        assert np.all(sample.sinkage_m > GUSEV_SOIL.sinkage_m)  # deeper with the slip
    assert 0.3 <= min(held) < 0.32 and 0.58 < max(held) <= 0.6
    assert np.mean(held) == pytest.approx(0.45, abs=0.02)  # uniform: the midpoint
    turn = model.turn(np.full(5, 0.2), model.noise(np.full(5, 0.01)))
    assert 0.3 <= float(turn.slip[0]) <= 0.6 and np.all(turn.slip == turn.slip[0])
    # creep still follows the terramechanics: downslope on a cross slope
    cross = model.drive(np.zeros(3), np.full(3, 0.3), model.noise(np.full(3, 0.01)))
    assert np.all(cross.creep < 0.0)


@pytest.mark.parametrize("bad", [(0.5, 0.4), (-0.1, 0.5), (0.2, 1.0), (0.2,), "0.3-0.6"])
def test_a_bad_slip_range_is_rejected(bad: object) -> None:
    with pytest.raises(InputError, match="slip_range"):
        SlipParams(slip_range=bad)  # type: ignore[arg-type]
