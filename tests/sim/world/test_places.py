"""Scenario places (sim/world/places.py): selectable like sites, with the slopes and the soil
they claim, measured on the terrain the rover drives on; the existing MER visual odometry
converges on the Endurance-like slope (Cheng, Maimone and Matthies 2005, sec. 4.1: VO on
Endurance's sand slopes), and the rover bogs down in the Purgatory-like ripple (sol 446)."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest

from sequences import commands as cmd
from sim.errors import InputError
from sim.loop.rover_sim import RoverSim
from sim.loop.session import RoverSession
from sim.rover.geometry import MER_GEOMETRY
from sim.rover.settle import settle
from sim.world.places import PLACE_NAMES, PURGATORY_HEIGHT_M, PURGATORY_X_M
from sim.world.sites import SITE_NAMES, make_terrain, site
from sim.world.terrain import SAND_TRAP

DAY = datetime(2004, 4, 15, 3, 0, tzinfo=UTC)  # mid-morning at Meridiani: the Navcam sees
R = MER_GEOMETRY.wheel_radius_m


def test_places_are_named_like_sites_and_sit_at_meridiani() -> None:
    assert PLACE_NAMES == ("meridiani:endurance_slope", "meridiani:purgatory_ripple")
    assert SITE_NAMES == ("gusev", "meridiani", "eq22", "flat")  # the sites are unchanged
    for name in PLACE_NAMES:
        where = site(name)
        assert where.name == name and where.mission == "opportunity"
        assert (where.lat_deg, where.lon_east_deg) == (
            site("meridiani").lat_deg,
            site("meridiani").lon_east_deg,
        )
        assert float(make_terrain(name, 3).height_m(0.0, 0.0)) == pytest.approx(0.0, abs=1e-9)
    with pytest.raises(InputError, match="meridiani:purgatory_ripple"):
        site("meridiani:nowhere")


def _slope_deg(terrain: object, x: np.ndarray, y: np.ndarray, half_m: float) -> np.ndarray:
    """Slope over a rover-scale baseline (2 half_m) from heights alone."""
    h = terrain.height_m  # type: ignore[attr-defined]
    gx = (h(x + half_m, y) - h(x - half_m, y)) / (2.0 * half_m)
    gy = (h(x, y + half_m) - h(x, y - half_m)) / (2.0 * half_m)
    return np.degrees(np.arctan(np.hypot(gx, gy)))


def test_the_endurance_slope_is_17_to_24_deg_of_loose_sand() -> None:
    terrain = make_terrain("meridiani:endurance_slope", 3)
    assert terrain.soil.name == "meridiani_sand"
    # up and down the fall line through the origin (North), and across it (East), 1 m baseline
    along = np.linspace(-14.0, 16.0, 61)
    up = _slope_deg(terrain, along, np.zeros_like(along), 0.5)
    across = _slope_deg(terrain, np.zeros_like(along), along, 0.5)
    for slopes in (up, across):
        assert slopes.min() >= 17.0 and slopes.max() <= 24.0
    assert up[0] < 19.0 and up[-1] > 22.0  # steeper towards the rim, as the wall is built
    # the rover's own measure: its attitude at rest at the origin, facing up the wall
    sim = RoverSim("meridiani:endurance_slope", 3, DAY)
    pitch_deg = math.degrees(float(sim.drive_state.suspension()[2]))
    assert 17.0 <= abs(pitch_deg) <= 24.0


def test_vo_converges_on_the_endurance_slope() -> None:
    session = RoverSession("meridiani:endurance_slope", 7, DAY)
    p0 = session.sim.drive_state.p_s.copy()
    report = session.execute(cmd.DriveStraight(distance_m=0.7, vo=True))
    assert report.status == "completed", report.reason
    assert report.details["vo_steps"] == 1 and report.details["vo_updates"] == 1
    truth = session.sim.drive_state.p_s - p0
    assert session.sim.drive_state.slip > 0.2  # uphill on loose sand: wheel odometry is long
    est = np.asarray(session.nate.p_s) - p0
    # VO put the position back within a few cm where the wheels were off by tens
    assert np.hypot(*(est - truth)[:2]) < 0.05
    assert 0.7 - np.hypot(*truth[:2]) > 0.15


def test_the_rover_bogs_down_in_the_purgatory_ripple() -> None:
    terrain = make_terrain("meridiani:purgatory_ripple", 3)
    x = np.linspace(0.0, 8.0, 161)
    crest = terrain.height_m(x, 0.0) - terrain.height_m(x, 0.0).min()
    assert PURGATORY_HEIGHT_M - 0.1 < crest.max() < PURGATORY_HEIGHT_M + 0.1
    assert abs(x[np.argmax(crest)] - PURGATORY_X_M) < 0.3
    sim = RoverSim("meridiani:purgatory_ripple", 3, DAY, x_m=1.5)
    assert sim.soil_at(PURGATORY_X_M, 0.0) is SAND_TRAP
    assert sim.soil_at(0.0, 0.0).name == "meridiani_sand"
    seg = sim.drive_straight(3.0)
    end = sim.drive_state.p_s
    # it rolled 3 m of wheel but stopped at the ripple's foot, 1.25 m on
    edge = PURGATORY_X_M - 1.25
    assert edge <= end[0] < edge + 0.1
    assert seg.truth.slip[-20:].min() >= 0.9
    # sunk to the hubs: the end pose is the rover settled with 0.9 r of sinkage, a body
    # 0.9 r - 1 cm lower than on the plains' sand at the same spot
    x, y, yaw = end[:1], end[1:2], np.array([sim.drive_state.yaw_rad])
    deep = settle(terrain, x, y, yaw, sinkage_m=0.9 * R).p_s[0, 2]
    plains = settle(terrain, x, y, yaw, sinkage_m=0.01).p_s[0, 2]
    assert end[2] == pytest.approx(deep, abs=2e-3)
    assert deep - plains == pytest.approx(0.9 * R - 0.01, abs=0.02)
