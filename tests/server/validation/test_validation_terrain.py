"""The ground's map in the validation context (``server.validation.terrain``): cut down from the
rover's ground map, carried as plain data to the validation worker, and the tilt warnings it
gives through the REST route; and the mobility limits the rover reports holding."""

from __future__ import annotations

import asyncio
import math
import pickle
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient
from scipy.ndimage import gaussian_filter

import server.validation.pool as pool_module
from sequences import commands as cmd
from sequences.terrain_check import footprint_attitude
from sequences.terrain_grid import TerrainGrid
from server.app import ServerConfig, create_app, data_dir_url
from server.runtime import ROVERS, RoverRuntime
from server.terrain.feed import ground_feed
from server.terrain.ground_map import GroundMap
from server.validation.context import RoverSite, rover_site, stored_rover_site
from server.validation.pool import ValidationPool
from server.validation.terrain import CROP_HALF_M, GRID_CELL_M, coarse_map, crop

TOKEN = "validation-terrain-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
SPIRIT = RoverSite("spirit", -0.2555, 3.0658, 1.6e8, aqf="Fine")


def _ground_map(
    heights: Any, imaged: bool, half_m: float = 40.0, cell_m: float = 0.25
) -> GroundMap:
    """A hand-made ground map of ``heights(north, east)`` around the mission origin."""
    axis = np.arange(-half_m, half_m + cell_m / 2, cell_m)
    north, east = np.meshgrid(axis, axis, indexing="ij")
    shape = north.shape
    return GroundMap(
        float(axis[0]), float(axis[0]), cell_m, np.asarray(heights(north, east), dtype=np.float64),
        np.full(shape, 0.05 if imaged else 0.35), np.full(shape, 0.3), np.full(shape, np.nan),
        np.full(shape, imaged),
    )  # fmt: skip


def _steep(north: Any, east: Any) -> Any:
    """Level, then rising at 35 deg northward from 12 m North of the mission origin."""
    return np.maximum(0.0, north - 12.0) * math.tan(math.radians(35.0))


def test_the_map_is_cropped_around_the_rover_and_merged_to_coarser_cells() -> None:
    slope_n, slope_e = 0.1, -0.05
    gmap = _ground_map(lambda n, e: slope_n * n + slope_e * e, imaged=True, half_m=60.0)
    coarse = coarse_map(gmap)
    assert coarse.cell_m == GRID_CELL_M
    p_mission, p_s = (20.0, -10.0), (3.0, 4.0)
    grid = crop(coarse, p_mission, (p_mission[0] - p_s[0], p_mission[1] - p_s[1]), 7)
    assert grid is not None and grid.stereo_pairs == 7
    assert grid.site_origin_m == (17.0, -14.0)
    ny, nx = grid.shape
    north = grid.north0_m + grid.cell_m * np.arange(ny)
    east = grid.east0_m + grid.cell_m * np.arange(nx)
    assert north[0] >= p_mission[0] - CROP_HALF_M and north[-1] <= p_mission[0] + CROP_HALF_M
    assert east[-1] <= -10.0 + CROP_HALF_M and east[-1] > -10.0 + CROP_HALF_M - 1.0
    # a plane's block means are the plane at the blocks' centres: measured cells unsmoothed
    n, e = np.meshgrid(north, east, indexing="ij")
    assert np.allclose(grid.height_m, slope_n * n + slope_e * e, atol=1e-5)
    assert grid.imaged.all() and np.allclose(grid.sigma_m, 0.05)
    assert grid.height_m.dtype == np.float32
    assert crop(coarse, (500.0, 0.0), (0.0, 0.0), 0) is None  # the rover off the map


def test_the_orbital_dem_s_noise_is_not_read_as_tilt() -> None:
    """The orbital DEM's error on level ground (0.25 m, correlated over a 1 m post, as
    ``sim.world.orbital_map`` makes it): on the raw map the footprint tilts by degrees; on
    the smoothed map the validator takes, by about one."""
    rng = np.random.default_rng(7)
    noise = gaussian_filter(rng.normal(size=(321, 321)), 1.0 / 0.25)
    noise *= 0.25 / noise.std()
    gmap = _ground_map(lambda n, e: noise, imaged=False)
    smoothed = crop(coarse_map(gmap), (0.0, 0.0), (0.0, 0.0), 0)
    assert smoothed is not None
    raw = TerrainGrid(gmap.north0_m, gmap.east0_m, gmap.cell_m, gmap.height_m, gmap.sigma_m,
                      gmap.imaged, (0.0, 0.0))  # fmt: skip
    poses = rng.uniform(-20.0, 20.0, (400, 3))
    tilts = [
        np.degrees(np.maximum(*np.abs(footprint_attitude(g, *poses.T)))) for g in (raw, smoothed)
    ]
    assert np.median(tilts[0]) > 5.0
    assert np.median(tilts[1]) < 1.5


def test_the_context_with_its_map_pickles_small_and_the_worker_warns_with_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a steep patch stereo measured (no smoothing): 10 m North of the rover's reported pose
    grid = crop(coarse_map(_ground_map(_steep, imaged=True)), (2.0, 1.0), (0.0, 0.0), 3)
    assert grid is not None
    site = RoverSite(
        "spirit", -0.2555, 3.0658, 1.6e8, aqf="Fine", p_s_est=(2.0, 1.0), heading_rad=0.0,
        terrain=grid,
    )  # fmt: skip
    data = pickle.dumps(site)
    assert len(data) < 400_000
    again = pickle.loads(data)
    assert again.terrain is not None and np.array_equal(again.terrain.height_m, grid.height_m)
    assert again.context().terrain is again.terrain
    text = b"DRIVE_STRAIGHT distance_m=8\nDRIVE_STRAIGHT distance_m=20\n"
    pool = ValidationPool(1)
    pool.start(SPIRIT)
    try:
        monkeypatch.setattr(pool_module, "check_upload", _not_here)  # the worker's answer
        checked = asyncio.run(pool.check(text, "text/plain", site, False))
    finally:
        pool.stop()
    tilts = [d for d in checked.result.warnings if d.code == "tilt-limit"]
    assert [d.line for d in tilts] == [2]  # 8 m stop short of the foot, 10 m North
    message = tilts[0].message
    assert "up to 35.0 deg" in message and "from the rover's stereo" in message
    found = float(message.split(" m from the drive's start")[0].rsplit(" ", 1)[1])
    # between the front wheels reaching the foot (0.7 m ahead) and the rear ones
    assert 12.0 - 10.0 - 0.7 <= found <= 12.0 - 10.0 + 0.7


def _not_here(*_: Any) -> Any:
    raise AssertionError("validated in the server's process")


def test_the_rover_reports_the_mobility_limits_it_holds() -> None:
    runtime = RoverRuntime(ROVERS["spirit"])
    assert rover_site(runtime).mobility_limits is None
    runtime.session.execute(cmd.SetParam("mobility.tilt_limit_rad", 0.35))
    runtime._publish(runtime.session.take_frames())
    limits = rover_site(runtime).mobility_limits
    assert limits is not None and limits.tilt_limit_rad == 0.35


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, Any]]:
    """A server whose rover stands where it landed and has reported one frame, with a
    tilt limit of 0.1 deg, validating uploads in a worker."""
    config = ServerConfig(
        database_url=data_dir_url(Path(tmp_path_factory.mktemp("terrain"))),
        operator_token=TOKEN,
        start_clocks=False,
        validation_processes=1,
    )
    with TestClient(create_app(config)) as client:
        server = client.app.state.server  # type: ignore[attr-defined]
        runtime = server.rover("spirit")
        runtime.session.execute(cmd.SetParam("mobility.tilt_limit_rad", math.radians(0.1)))
        runtime._publish(runtime.session.take_frames())
        yield client, server


def _tilt_warnings(client: TestClient, text: str) -> list[dict[str, Any]]:
    r = client.post("/api/rovers/spirit/sequences", content=text, headers=AUTH)
    assert r.status_code == 201, r.text
    return [w for w in r.json()["warnings"] if w["code"].startswith("tilt")]


def test_an_upload_is_checked_on_the_rover_s_ground_map(
    served: tuple[TestClient, Any], monkeypatch: pytest.MonkeyPatch
) -> None:
    client, server = served
    monkeypatch.setattr(pool_module, "check_upload", _not_here)  # the worker's answers
    text = "SEQUENCE look\nDRIVE_STRAIGHT distance_m=2\n"
    assert _tilt_warnings(client, text) == []  # no ground map for the rover yet: silent
    ground_feed(server.rover("spirit"), server.store)  # the map the 3D view and advisor share
    [warned] = _tilt_warnings(client, text)
    assert warned["code"] == "tilt-limit" and warned["line"] == 2
    assert "0.0 m from the drive's start" in warned["message"]  # the real ground is not level
    assert "limit of 0.1 deg" in warned["message"] and "orbital DEM only" in warned["message"]
    # the same site the route validated with: the map around the rover's reported pose
    site = rover_site(server.rover("spirit"))
    assert site.terrain is not None and site.terrain.stereo_pairs == 0
    assert len(pickle.dumps(site)) < 400_000


def test_the_database_s_rover_site_has_its_map_and_limits(served: tuple[TestClient, Any]) -> None:
    """``roverops validate --rover`` without a server: the map rebuilt from the stored pairs
    (none here: the orbital DEM), the limits from the stored events."""
    _, server = served
    runtime = server.rover("spirit")
    runtime.checkpoint()
    server.writer.flush()
    site = stored_rover_site(server.store, "spirit")
    assert site is not None and site.terrain is not None
    assert site.mobility_limits is not None
    assert site.mobility_limits.tilt_limit_rad == pytest.approx(math.radians(0.1))
    live = rover_site(runtime)
    assert live.terrain is not None and site.terrain.site_origin_m == live.terrain.site_origin_m
    assert np.array_equal(site.terrain.height_m, live.terrain.height_m)  # the same map
    without = stored_rover_site(server.store, "spirit", ground_map=False)
    assert without is not None and without.terrain is None
