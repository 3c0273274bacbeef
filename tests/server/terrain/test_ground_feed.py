"""The ground's map fed from the pairs stored as they came down (``server.terrain.feed``): a
NAVCAM_STEREO pair run through the server refines the map where it looked, each stored pair is
taken once, and a map rebuilt from storage (a server restarted) is the same map."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from server.app import ServerConfig, create_app, data_dir_url
from server.terrain.feed import GROUND_HALF_M, ground_feed
from server.terrain.service import GroundMapService

TOKEN = "feed-admin-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    url = data_dir_url(Path(tmp_path_factory.mktemp("feed")))
    config = ServerConfig(database_url=url, operator_token=TOKEN, public_read=False)
    with TestClient(create_app(config)) as c:
        posted = c.post("/api/rovers/spirit/sequences", headers=AUTH,
                        content="SEQUENCE look\nNAVCAM_STEREO az_deg=0 el_deg=-35\n")  # fmt: skip
        assert posted.status_code == 201, posted.text
        c.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH)
        deadline = time.monotonic() + 120.0
        while not c.get("/api/rovers/spirit/images", headers=AUTH).json()["total"]:
            assert time.monotonic() < deadline, "the pair never reached storage"
            time.sleep(0.1)
        yield c


def test_a_stored_pair_refines_the_map_where_the_navcams_looked(client: TestClient) -> None:
    server = client.app.state.server  # type: ignore[attr-defined]
    runtime = server.rovers["spirit"]
    feed = ground_feed(runtime, server.store)
    assert ground_feed(runtime, server.store) is feed  # one per rover
    before = feed.service.ground_map()
    assert feed.catch_up() == 1 and feed.catch_up() == 0  # each pair taken once
    after = feed.service.ground_map()
    assert feed.service.version == 1 and after.imaged.sum() > 50
    # the measured cells lie ahead of the rover (the mast at az 0, heading as it stood)
    image = client.get("/api/rovers/spirit/images", headers=AUTH).json()["images"][0]
    p = np.asarray(image["p_mission_est"])
    i, j = np.nonzero(after.imaged)
    north = after.north0_m + i * after.cell_m - p[0]
    east = after.east0_m + j * after.cell_m - p[1]
    heading = np.degrees(np.arctan2(np.median(east), np.median(north)))
    q = image["q_b_ll_est"]  # yaw of the body in Local Level
    yaw = math.degrees(math.atan2(2 * (q[3] * q[2] + q[0] * q[1]), 1 - 2 * (q[1] ** 2 + q[2] ** 2)))
    assert abs((heading - yaw + 180.0) % 360.0 - 180.0) < 30.0
    assert np.all(after.sigma_m[after.imaged] < before.sigma_m[after.imaged])


def test_a_map_rebuilt_from_storage_is_the_same_map(client: TestClient) -> None:
    server = client.app.state.server  # type: ignore[attr-defined]
    runtime = server.rovers["spirit"]
    shared = ground_feed(runtime, server.store)
    shared.catch_up()
    start_n, start_e = runtime.session.sim.start_xy_m
    fresh = GroundMapService(runtime.spec.site, runtime.spec.seed, start_n, start_e,
                             half_m=GROUND_HALF_M)  # fmt: skip
    rebuilt = ground_feed(runtime, server.store, fresh)
    assert rebuilt.catch_up() == 1
    one, two = shared.service.ground_map(), fresh.ground_map()
    assert np.array_equal(one.height_m, two.height_m)
    assert np.array_equal(one.sigma_m, two.sigma_m)
