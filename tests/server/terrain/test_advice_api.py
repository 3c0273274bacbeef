"""``POST /api/rovers/{rover}/vo-advice`` (server.terrain.advice_api): an operator's advice for
a drive line, and bad requests refused with the reason."""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from server.app import Server, ServerConfig, create_app, data_dir_url
from server.terrain.feed import ground_feed
from server.terrain.ground_map import GroundMap
from sim.scenarios.scene_builder import (
    FEATURELESS,
    AlbedoPatch,
    RockSpec,
    build_scene,
    install_scene,
)
from sim.world.soil_patches import Circle

BOOTSTRAP = "bootstrap-token-for-tests"


@pytest.fixture
def api(tmp_path: Path) -> Iterator[tuple[TestClient, dict[str, str], dict[str, str]]]:
    config = ServerConfig(
        database_url=data_dir_url(tmp_path), operator_token=BOOTSTRAP, start_clocks=False
    )
    app = create_app(config)
    server: Server = app.state.server
    operator = server.accounts.add_user("ada", "operator").token
    viewer = server.accounts.add_user("vic", "viewer").token
    runtime = server.rovers["spirit"]
    runtime.set_clock(speed=math.inf)
    with TestClient(app) as client:
        r = client.post(
            "/api/rovers/spirit/commands",
            json={"command": "WAIT", "args": {"duration_s": 1}},
            headers={"Authorization": f"Bearer {operator}"},
        )
        assert r.status_code == 201, r.text
        for _ in range(3):  # the wait runs and its frames play out: a reported pose
            runtime._tick(0.05)
        yield client, {"Authorization": f"Bearer {operator}"}, {"Authorization": f"Bearer {viewer}"}


def _state(client: TestClient, auth: dict[str, str]) -> dict[str, object]:
    out: dict[str, object] = client.get("/api/rovers/spirit/state", headers=auth).json()
    return out


def test_advice_for_a_sequence_line(api: tuple[TestClient, dict[str, str], dict[str, str]]) -> None:
    client, auth, _ = api
    assert _state(client, auth).get("frame") is not None
    text = "SEQUENCE s\nDRIVE_STRAIGHT distance_m=1\nDRIVE_STRAIGHT distance_m=3 vo=on\n"
    r = client.post("/api/rovers/spirit/vo-advice", json={"text": text, "line": 3}, headers=auth)
    assert r.status_code == 200, r.text
    body = r.json()
    assert body["line"] == 3 and body["pairs"] == 5  # 3 m in 0.75 m steps: 5 pairs
    assert len(body["candidates"]) == 27  # 9 azimuths x 3 elevations
    best = body["recommended"]
    assert best is not None and best["ok"]
    assert best["overlap_min"] >= 0.6 and best["shadow_max"] <= 0.05
    assert body["arguments"] == f"vo_az_deg={best['az_deg']:g} vo_el_deg={best['el_deg']:g}"
    # the rule: no qualifying candidate predicts more features at its worst step
    assert all(c["features_min"] <= best["features_min"] for c in body["candidates"] if c["ok"])


def test_bad_requests_are_refused_with_the_reason(
    api: tuple[TestClient, dict[str, str], dict[str, str]],
) -> None:
    client, auth, viewer = api
    url = "/api/rovers/spirit/vo-advice"
    cases = [
        ({"command": "WAIT duration_s=5"}, 422, "not a drive"),
        ({"command": "DRIVE_STRAIGHT distance_m=oops"}, 422, "line 1"),
        ({"text": "DRIVE_STRAIGHT distance_m=1", "line": 7}, 422, "no command on that line"),
        ({"text": "DRIVE_STRAIGHT distance_m=1"}, 422, "line"),
        ({}, 422, "either command"),
        ({"command": "DRIVE_STRAIGHT distance_m=1", "extra": 1}, 422, "extra"),
        ({"command": 5}, 422, "string"),
    ]
    for body, status, words in cases:
        r = client.post(url, json=body, headers=auth)
        assert r.status_code == status, (body, r.text)
        assert words in r.text, (body, r.text)
    assert (
        client.post(
            url, json={"command": "DRIVE_STRAIGHT distance_m=1"}, headers=viewer
        ).status_code
        == 403
    )
    assert (
        client.post(
            "/api/rovers/nobody/vo-advice",
            json={"command": "DRIVE_STRAIGHT distance_m=1"},
            headers=auth,
        ).status_code
        == 404
    )


def test_the_advice_reads_the_ground_not_the_simulator(
    api: tuple[TestClient, dict[str, str], dict[str, str]],
) -> None:
    """The simulator's hidden terrain and the true pose change, the ground's map and the
    reported pose do not: the advice is the same, number for number. The ground's map
    changes: the advice follows it."""
    client, auth, _ = api
    url, body = "/api/rovers/spirit/vo-advice", {"command": "DRIVE_STRAIGHT distance_m=2 vo=on"}
    before = client.post(url, json=body, headers=auth).json()
    server: Server = client.app.state.server  # type: ignore[attr-defined]
    runtime = server.rovers["spirit"]
    sim = runtime.session.sim
    scene = build_scene(
        "meridiani", 7, [RockSpec(2.0, 1.0, 0.4), RockSpec(2.5, -1.5, 0.3)],
        [AlbedoPatch(Circle(2.0, 2.0, 1.5), FEATURELESS)],
    )  # fmt: skip
    with runtime.lock:
        install_scene(sim, scene)  # new terrain under the rover: its true pose moves too
    assert sim.terrain is scene
    assert client.post(url, json=body, headers=auth).json() == before
    n = 81
    flat, ones = np.zeros((n, n)), np.ones((n, n))
    sand = GroundMap(-20.0, -20.0, 0.5, flat, 0.1 * ones, 0.13 * ones, flat, ones > 0.0)
    feed = ground_feed(runtime, server.store)  # the map the ground has: now featureless sand
    feed.service.ground_map = lambda: sand  # type: ignore[method-assign]
    after = client.post(url, json=body, headers=auth).json()
    assert after["map"].startswith("the rover's ground map")
    assert all(c["features_min"] == 0.0 for c in after["candidates"])
    assert after["candidates"] != before["candidates"]
