"""Slip on the soil under the rover (sim/rover/patch_slip.py): without patches every figure
is the base model's bit for bit (pinned also against the commit before soil patches); a
sand trap holds the rover at >= 90 % slip on level ground with the wheels sunk to 0.9 of
their radius, checked against Bekker's compaction resistance and the soil's friction
(Wong ch. 2; Bekker 1969); a drive into one bogs down; patches survive a checkpoint."""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import fields
from datetime import UTC, datetime

import numpy as np
import pytest

from estimation.mars_constants import MARS_GRAVITY_M_S2
from sim.loop.rover_sim import RoverSim
from sim.rover import drive
from sim.rover.geometry import MER_GEOMETRY
from sim.rover.patch_slip import PatchSlipModel
from sim.rover.slip import SlipModel
from sim.world.sites import make_terrain
from sim.world.soil_patches import Circle, SoilMap, SoilPatch, sand_trap
from sim.world.terrain import GUSEV_SOIL, MERIDIANI_SAND, SAND_TRAP

START = datetime(2004, 4, 14, 15, 0, tzinfo=UTC)
R = MER_GEOMETRY.wheel_radius_m
DEG = math.pi / 180.0


def _segments_digest(sim: RoverSim) -> str:
    h = hashlib.sha256()
    for seg in (sim.drive_straight(1.2), sim.drive_arc(3.0, 0.3), sim.turn_in_place(-0.5)):
        for f in fields(seg.truth):
            h.update(np.ascontiguousarray(getattr(seg.truth, f.name)).tobytes())
    h.update(np.ascontiguousarray(sim.drive_state.p_s).tobytes())
    return h.hexdigest()[:16]


@pytest.mark.parametrize(
    "site_name,digest", [("meridiani", "9a0d031bfec1cc1d"), ("gusev", "cc87de36c2a0b3c7")]
)
def test_without_patches_the_drives_are_those_of_the_commit_before_soil_patches(
    site_name: str, digest: str
) -> None:
    # Recorded on the base commit (453a1dd) with this very function: a straight, an arc and
    # a turn in place, seed 11, truth for truth.
    assert _segments_digest(RoverSim(site_name, 11, START)) == digest


@pytest.mark.parametrize("far_patch", [False, True])
def test_without_a_patch_under_the_rover_the_model_is_the_base_model(far_patch: bool) -> None:
    terrain = make_terrain("meridiani", 5)
    soil_map = SoilMap(terrain.soil)
    if far_patch:  # a patch nowhere near: the draws and the arithmetic stay the base's
        soil_map.add("far", sand_trap(500.0, 500.0, 3.0))
    base = SlipModel(terrain.soil, np.random.default_rng(9))
    patched = PatchSlipModel(terrain.soil, np.random.default_rng(9), soil_map=soil_map)
    ends = []
    for model in (base, patched):
        start = drive.initial_state(terrain, 0.0, slip_model=model)
        a, s1 = drive.drive_straight(terrain, start, 1.0, model)
        b, s2 = drive.turn_in_place(terrain, s1, 0.4, model)
        ends.append((a, b, s2))
    for x, y in zip(ends[0][:2], ends[1][:2], strict=True):
        for f in fields(x):
            np.testing.assert_array_equal(getattr(x, f.name), getattr(y, f.name))
    np.testing.assert_array_equal(ends[0][2].p_s, ends[1][2].p_s)


def _trap_model() -> PatchSlipModel:
    soil_map = SoilMap(MERIDIANI_SAND, {"trap": sand_trap(0.0, 0.0, 5.0)})
    return PatchSlipModel(MERIDIANI_SAND, np.random.default_rng(3), soil_map=soil_map)


def test_a_sand_trap_cannot_carry_its_own_rolling_resistance() -> None:
    # Independent figures: Bekker's compaction resistance of a rigid wheel (n = 1) at the
    # trap's static sinkage against the Mohr-Coulomb limit (no cohesion) on level ground.
    f_r = 0.75 * math.sqrt(SAND_TRAP.sinkage_m / (2.0 * R))
    assert f_r > math.tan(SAND_TRAP.friction_angle_deg * DEG)
    # ... while the plains' sand carries it easily (a few % slip)
    f_sand = 0.75 * math.sqrt(MERIDIANI_SAND.sinkage_m / (2.0 * R))
    assert f_sand < 0.5 * math.tan(MERIDIANI_SAND.friction_angle_deg * DEG)


def test_on_a_sand_trap_level_slip_is_over_90_percent_and_the_wheels_sink_to_the_hubs() -> None:
    model = _trap_model()
    n = 400
    noise = model.noise(np.full(n, 0.0047))
    x, y = np.linspace(-2.0, 2.0, n), np.zeros(n)
    sample = model.drive(np.zeros(n), np.zeros(n), noise, x_m=x, y_m=y)
    assert sample.slip.min() >= 0.9
    assert sample.slip.max() <= 1.0  # spinning in place, never pushed backwards on the level
    assert sample.sinkage_m.min() >= 0.85 * R and sample.sinkage_m.max() <= 0.9 * R + 1e-12
    assert np.abs(sample.creep).max() < 0.05  # held sideways by the ruts
    turn = model.turn(np.zeros(n), noise, x_m=x, y_m=y)
    assert turn.slip.min() >= 0.9 and turn.sinkage_m.max() <= 0.9 * R + 1e-12
    at_rest = model.sinkage_m(0.0, x_m=0.0, y_m=0.0)
    assert float(at_rest) == SAND_TRAP.sinkage_m  # static sinkage where the rover stands
    assert float(model.sinkage_m(0.0, x_m=9.0, y_m=0.0)) == MERIDIANI_SAND.sinkage_m


def test_steep_enough_the_rover_slides_back_out_of_a_sand_trap() -> None:
    model = _trap_model()
    zero = np.zeros((1, 2))
    # the grade alone beats the traction limit: W sin 30° > W cos 30° tan 18°
    weight = MER_GEOMETRY.mass_kg * MARS_GRAVITY_M_S2
    assert weight * math.sin(30 * DEG) > weight * math.cos(30 * DEG) * math.tan(18 * DEG)
    steep = model.drive(np.array([30 * DEG]), np.zeros(1), zero, x_m=[0.0], y_m=[0.0])
    assert float(steep.slip[0]) == model.params.slip_max
    gentle = model.drive(np.array([10 * DEG]), np.zeros(1), zero, x_m=[0.0], y_m=[0.0])
    assert float(gentle.slip[0]) == 1.0


def test_a_mixed_batch_takes_each_steps_soil() -> None:
    soil_map = SoilMap(MERIDIANI_SAND, {"gusev": SoilPatch(GUSEV_SOIL, Circle(5.0, 0.0, 1.0))})
    model = PatchSlipModel(MERIDIANI_SAND, np.random.default_rng(1), soil_map=soil_map)
    x = np.array([0.0, 5.0, 10.0, 5.5])
    along = np.full(4, 15 * DEG)
    noise = np.zeros((4, 2))
    mixed = model.drive(along, np.zeros(4), noise, x_m=x, y_m=np.zeros(4))
    sand = SlipModel(MERIDIANI_SAND, no_slip=False, rng=np.random.default_rng(1))
    gusev = SlipModel(GUSEV_SOIL, rng=np.random.default_rng(1))
    expected = [
        float(m.drive(along[:1], np.zeros(1), noise[:1]).slip[0])
        for m in (sand, gusev, sand, gusev)
    ]
    np.testing.assert_array_equal(mixed.slip, expected)


def test_a_drive_into_a_sand_trap_bogs_down_and_goes_on_once_it_is_lifted() -> None:
    sim = RoverSim("meridiani", 4, START)
    sim.add_soil_patch("trap", sand_trap(2.0, 0.0, 1.0))  # graded in over its outer 0.3 m
    seg = sim.drive_straight(2.5)
    x_end = float(sim.drive_state.p_s[0])
    assert 1.0 <= x_end < 1.3  # the body stopped in the trap's rim, 1 m on
    assert seg.truth.slip[-10:].min() >= 0.9
    assert sim.totals.distance_odometry_m > 1.8 * sim.totals.distance_truth_m
    sunk = sim.slip.sinkage_m(seg.truth.slip[-1], x_m=x_end, y_m=sim.drive_state.p_s[1])
    assert float(sunk) >= 0.8 * R
    # sinking in over the rim: never more than 2 cm lower in one control step ...
    assert np.diff(seg.truth.p_s[:, 2]).max() < 0.02
    sim.remove_soil_patch("trap")
    sim.drive_straight(1.0)
    assert float(sim.drive_state.p_s[0]) - x_end > 0.9  # the plains' few % of slip again


def test_without_a_rim_the_rover_drops_into_a_trap_in_one_step() -> None:
    sim = RoverSim("meridiani", 4, START)
    sim.add_soil_patch("trap", sand_trap(2.0, 0.0, 1.0, rim_m=0.0))
    seg = sim.drive_straight(2.5)
    assert 1.0 <= float(sim.drive_state.p_s[0]) < 1.01  # stopped at the edge
    # ... where a sharp edge drops the body by the extra sinkage at once (0.9 r - 1 cm)
    assert np.diff(seg.truth.p_s[:, 2]).max() == pytest.approx(0.9 * R - 0.01, abs=0.01)


def test_soil_patches_survive_a_checkpoint() -> None:
    a = RoverSim("meridiani", 6, START)
    a.add_soil_patch("trap", sand_trap(1.0, 0.0, 0.5))
    state = a.state()
    json.dumps(state["soil_patches"])  # plain data
    b = RoverSim("meridiani", 6, START)
    b.load_state(state)
    assert b.soil_map.patches() == a.soil_map.patches()
    a.drive_straight(1.5)
    b.drive_straight(1.5)
    np.testing.assert_array_equal(a.drive_state.p_s, b.drive_state.p_s)
    assert float(a.drive_state.p_s[0]) < 1.0  # the trap held both
