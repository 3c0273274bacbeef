"""The scene builder (sim.scenarios.scene_builder): rocks where they are placed and as tall as
told, albedo patches as described, drawn by the Navcam, and a rover settled on the scene."""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest

from sim.errors import InputError
from sim.loop.rover_sim import RoverSim
from sim.scenarios.scene_builder import (
    FEATURELESS,
    TEXTURED,
    AlbedoPatch,
    RockSpec,
    build_scene,
    install_scene,
)
from sim.sensors.navcam.texture import band_limited_albedo
from sim.world.albedo import AlbedoStyle
from sim.world.sites import MERIDIANI_ALBEDO, make_terrain
from sim.world.soil_patches import Circle, Polygon

STYLE = AlbedoStyle(mean=0.2, contrast=0.3)


def test_rocks_stand_where_placed_as_tall_as_told() -> None:
    scene = build_scene(
        "flat", 0, [RockSpec(2.0, 1.0, 0.3, height_m=0.12), RockSpec(-1.0, 0.5, 0.2)]
    )
    assert float(scene.height_m(2.0, 1.0)) == pytest.approx(0.12, abs=1e-3)
    assert float(scene.height_m(-1.0, 0.5)) == pytest.approx(0.1, abs=1e-3)  # half its diameter
    assert float(scene.height_m(2.0, 1.0 + 0.16)) == 0.0  # beyond its radius: the ground
    assert float(scene.height_m(5.0, 5.0)) == 0.0
    # on a site's ground the rock sits on it: its top above the ground beside it
    site = build_scene("meridiani", 4, [RockSpec(3.0, 3.0, 0.3, height_m=0.15)], site_rocks=False)
    ground = make_terrain("meridiani", 4)
    beside = float(ground.height_m(3.0, 3.5))
    assert float(site.height_m(3.0, 3.0)) - beside == pytest.approx(0.15, abs=0.02)


def test_patches_set_the_albedo_topmost_first() -> None:
    square = Polygon(((0.0, 0.0), (0.0, 4.0), (4.0, 4.0), (4.0, 0.0)))
    scene = build_scene("meridiani", 2, [], [
        AlbedoPatch(square, TEXTURED, style=STYLE, seed=5),
        AlbedoPatch(Circle(1.0, 1.0, 0.5), FEATURELESS, albedo=0.1),
    ])  # fmt: skip
    rng = np.random.default_rng(0)
    inside = rng.uniform(2.0, 3.9, (2, 500))
    sand = np.array([[1.0, 1.2], [1.0, 0.9]])
    assert np.all(scene.albedo(sand[0], sand[1]) == 0.1)  # the featureless disc, on top
    textured = scene.albedo(inside[0], inside[1])
    assert textured.std() > 0.02 and abs(textured.mean() - 0.2) < 0.03
    outside = rng.uniform(-9.0, -5.0, (2, 500))  # the site's own texture there
    base = make_terrain("meridiani", 2)
    assert np.allclose(scene.albedo(outside[0], outside[1]), base.albedo(outside[0], outside[1]))
    # the renderer's call: each texture band-limited by the numba kernel, as the sites' are
    fp = np.full(500, 0.01)
    assert np.allclose(scene.albedo_band_limited(outside[0], outside[1], fp),
                       band_limited_albedo(base.texture, outside[0], outside[1], fp))  # fmt: skip
    plain = build_scene("meridiani", 2, site_texture=False, base_albedo=0.15)
    assert np.all(plain.albedo(outside[0], outside[1]) == 0.15)
    assert MERIDIANI_ALBEDO.mean == pytest.approx(0.13)


def test_a_rover_on_the_scene_sees_its_rock_and_patch() -> None:
    sim = RoverSim("flat", 1, datetime(2004, 3, 1, 12, tzinfo=UTC), yaw_rad=0.0)
    rock = RockSpec(2.2, 0.0, 0.3, height_m=0.15)
    sand = AlbedoPatch(Circle(2.0, 0.3, 0.25), FEATURELESS, albedo=0.1)
    scene = build_scene("flat", 1, [rock], [AlbedoPatch(Circle(0.0, 0.0, 50.0), TEXTURED,
                                                        style=STYLE, seed=2), sand])  # fmt: skip
    install_scene(sim, scene)
    assert sim.terrain is scene
    assert sim.drive_state.p_s[0] == pytest.approx(0.0, abs=1e-9)
    pair = sim.navcam_pair(0.0, math.radians(-35.0), noise=False)
    cam = pair.rig.camera
    # the rock's top, straight ahead, is nearer than the flat ground behind it would be
    u, v = pair.rig.camera.project(pair.R_s_cam().T @ (np.array([2.2, 0.0, -0.15])
                                                       - pair.eye_centres_s()[0]))  # fmt: skip
    row, col = round(float(v)), round(float(u))
    assert 0 <= row < cam.height_px and 0 <= col < cam.width_px
    depth_flat = pair.depth_left_m[row, col]
    sim_flat = RoverSim("flat", 1, datetime(2004, 3, 1, 12, tzinfo=UTC), yaw_rad=0.0)
    install_scene(sim_flat, build_scene("flat", 1))
    assert (
        depth_flat
        < sim_flat.navcam_pair(0.0, math.radians(-35.0), noise=False).depth_left_m[row, col]
    )
    # the featureless disc images uniform (its pixels' spread is the shading's, tiny on flat ground)
    u, v = cam.project(pair.R_s_cam().T @ (np.array([2.0, 0.3, 0.0]) - pair.eye_centres_s()[0]))
    patch = pair.left[int(v) - 3 : int(v) + 4, int(u) - 3 : int(u) + 4]
    around = pair.left[int(v) - 3 : int(v) + 4, int(u) - 300 : int(u) - 293]
    assert patch.std() < 0.2 * around.std()


def test_bad_scenes_are_refused() -> None:
    with pytest.raises(InputError, match="base"):
        build_scene("moon", 0)
    with pytest.raises(InputError, match="diameter_m"):
        RockSpec(0.0, 0.0, 0.0)
    with pytest.raises(InputError, match="style"):
        AlbedoPatch(Circle(0.0, 0.0, 1.0), TEXTURED)
    with pytest.raises(InputError, match="kind"):
        AlbedoPatch(Circle(0.0, 0.0, 1.0), "shiny")
    with pytest.raises(InputError, match="aspect"):
        RockSpec(0.0, 0.0, 0.2, aspect=1.5)
