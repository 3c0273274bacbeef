"""Telemetry at a glance (``server.channels``) and the live timeline's command notices,
against a real app on a temporary SQLite database: a sequence runs at full speed, then any
numeric channel is read back over its sol (the stored frames' own values, decimated keeping
each bucket's min and max), bad requests get a 4xx naming the problem, and a WebSocket
client is told of each command as the sol timeline lists it."""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from fastapi.testclient import TestClient

from server.api.telemetry_csv import CSV_COLUMNS, CSV_VECTORS
from server.app import ServerConfig, create_app, data_dir_url
from server.channels import (
    MAX_POINTS,
    MAX_SOLS,
    decimate,
    frame_channels,
    is_truth,
    side_channels,
)
from tests.server.test_server_restart import _wait

TOKEN = "channels-test-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
SEQ = "SEQUENCE channels\nNADIR_UPDATE\nDRIVE_STRAIGHT distance_m=2\n"


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    """A sequence run to completion on spirit at full speed; opportunity idles paused."""
    url = data_dir_url(tmp_path_factory.mktemp("channels"))
    app = create_app(ServerConfig(database_url=url, operator_token=TOKEN, initial_speed=1.0))
    with TestClient(app) as c:
        c.post("/api/rovers/opportunity/clock", json={"action": "pause"}, headers=AUTH)
        c.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH)
        r = c.post("/api/rovers/spirit/sequences", content=SEQ, headers=AUTH)
        assert r.status_code == 201, r.text
        seq = r.json()["id"]
        _wait(lambda: c.get(f"/api/sequences/{seq}").json()["status"] == "completed")
        c.post("/api/rovers/spirit/clock", json={"action": "pause"}, headers=AUTH)
        yield c


def _sol_frames(client: TestClient, sol: int) -> list[dict[str, Any]]:
    server = client.app.state.server  # type: ignore[attr-defined]
    server.writer.flush()
    t0, t1 = server.store.sol_range("spirit", sol)
    frames: list[dict[str, Any]] = server.store.frames("spirit", t0, t1, with_truth=True)
    return frames


def test_every_channel_is_a_numeric_csv_column_and_truth_is_marked() -> None:
    """The channels are named as the CSV's columns; the figures scored against truth and
    every *_true field are marked, the rover's own figures are not."""
    columns = set(CSV_COLUMNS) | {f"{v}_{i}" for v, n in CSV_VECTORS.items() for i in range(n)}
    channels = frame_channels()
    assert set(channels) <= columns
    assert {"hga_margin_deg", "imu_integration_s", "p_mission_est_2", "q_b_ll_true_3"} <= set(
        channels
    )
    assert not {"t_s", "sol", "lmst_h", "aqf", "nate_mode", "command", "earth_up"} & set(channels)
    truth = {n for n, c in channels.items() if c.truth}
    assert {"position_error_m", "attitude_error_deg", "hga_error_deg", "hga_margin_deg"} <= truth
    assert {"p_mission_true_0", "sun_ll_true_1"} <= truth
    assert not {"imu_integration_s", "tilt_est_deg", "p_mission_est_0", "site_index"} & truth
    # issue 21: the true joint angles (the encoders' are the rover's) and earth_up are truth
    joints = {"rocker_deg", "bogie_deg_0", "bogie_deg_1"} | {f"steer_deg_{i}" for i in range(4)}
    assert joints <= truth
    assert is_truth("earth_up") and is_truth("bogie_deg") and not is_truth("aqf")
    side = side_channels(["kinematic_ekf"])
    assert side["kinematic_ekf_position_error_m"].truth
    assert not side["kinematic_ekf_p_mission_1"].truth


def test_the_channel_list_names_units_and_the_truth_view(client: TestClient) -> None:
    listed = {c["name"]: c for c in client.get("/api/rovers/spirit/channels").json()}
    assert listed["hga_margin_deg"] == {"name": "hga_margin_deg", "unit": "deg", "truth": True}
    assert listed["p_mission_est_0"] == {"name": "p_mission_est_0", "unit": "m", "truth": False}
    assert listed["imu_integration_s"]["unit"] == "s"


@pytest.mark.parametrize("name", ["imu_integration_s", "p_mission_est_0", "hga_margin_deg"])
def test_a_channel_is_the_stored_frames_values(client: TestClient, name: str) -> None:
    sol = client.get("/api/rovers/spirit/sols").json()[-1]
    frames = _sol_frames(client, sol)
    got = client.get(
        f"/api/rovers/spirit/channels/{name}",
        params={"sol_from": sol, "sol_to": sol, "max_points": MAX_POINTS},
    ).json()
    assert len(frames) <= MAX_POINTS and not got["decimated"]
    read = frame_channels()[name].read
    expected = [read(f) for f in frames]
    assert got["t_s"] == [f["t_s"] for f in frames]
    assert got["lmst_h"] == [f["lmst_h"] for f in frames]
    assert got["sol"] == [sol] * len(frames)
    assert got["values"] == [None if v is None or not math.isfinite(v) else v for v in expected]
    assert any(v is not None for v in got["values"])
    assert got["name"] == name


def test_decimation_keeps_each_buckets_min_and_max(client: TestClient) -> None:
    sol = client.get("/api/rovers/spirit/sols").json()[-1]
    full = client.get(
        "/api/rovers/spirit/channels/position_error_m",
        params={"sol_from": sol, "max_points": MAX_POINTS},
    ).json()
    small = client.get(
        "/api/rovers/spirit/channels/position_error_m",
        params={"sol_from": sol, "max_points": 30},
    ).json()
    assert small["decimated"] and len(small["values"]) <= 30 < len(full["values"])
    finite = [v for v in full["values"] if v is not None]
    kept = [v for v in small["values"] if v is not None]
    assert max(kept) == max(finite) and min(kept) == min(finite)
    assert small["t_s"] == sorted(small["t_s"])
    assert set(small["t_s"]) <= set(full["t_s"])  # real frames, not averages


def test_a_one_frame_spike_survives_decimation() -> None:
    t = [float(i) for i in range(10_000)]
    values: list[float | None] = [math.sin(i / 300.0) for i in range(10_000)]
    values[4321] = 50.0
    values[7000] = None  # a gap stays a gap
    keep = decimate(t, values, 60)
    assert len(keep) <= 60 and list(keep) == sorted(keep)
    assert 4321 in keep and 7000 in keep
    assert min(values[i] for i in keep if values[i] is not None) == pytest.approx(-1.0, abs=1e-3)


def reference_decimate(t: list[float], values: list[float | None], max_points: int) -> list[int]:
    """The decimation as it was written first, one bucket at a time in Python: the
    reference the array version must agree with, index for index."""
    n = len(t)
    if n <= max_points:
        return list(range(n))
    buckets = max(1, max_points // 3)
    t0, span = t[0], (t[-1] - t[0]) or 1.0
    keep: list[int] = []
    start = 0
    for b in range(buckets):
        end = n if b == buckets - 1 else start
        edge = t0 + span * (b + 1) / buckets
        while end < n and t[end] < edge:
            end += 1
        lo = hi = gap = None
        for i in range(start, end):
            v = values[i]
            if v is None:
                gap = i if gap is None else gap
                continue
            if lo is None or v < values[lo]:  # type: ignore[operator]
                lo = i
            if hi is None or v > values[hi]:  # type: ignore[operator]
                hi = i
        keep.extend(sorted({i for i in (lo, hi, gap) if i is not None}))
        start = end
    return keep


@pytest.mark.parametrize("seed", range(6))
def test_the_array_decimation_keeps_what_the_loop_kept(seed: int) -> None:
    """Uneven times (bursts, jumps, repeated times), gaps, runs of ties and buckets of
    nothing but gaps: the same indices as the per-bucket loop."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(500, 5000))
    t = np.cumsum(rng.choice([0.0, 0.125, 1.0, 600.0], size=n, p=[0.05, 0.6, 0.3, 0.05]))
    values: list[float | None] = [float(v) for v in rng.integers(-3, 4, size=n)]
    for i in rng.choice(n, size=n // 10, replace=False):
        values[i] = None
    values[n // 2 : n // 2 + n // 20] = [None] * (n // 20)
    for max_points in (4, 30, 301, n - 1, n):
        expected = reference_decimate(list(t), values, max_points)
        assert decimate(t, values, max_points).tolist() == expected, max_points


@pytest.mark.parametrize(
    ("path", "params", "status", "says"),
    [
        ("channels/no_such", {}, 404, "known: "),
        ("channels/aqf", {}, 404, "unknown channel 'aqf'"),
        ("channels/hga_margin_deg", {"sol_from": 5, "sol_to": 4}, 422, "sol_to"),
        ("channels/hga_margin_deg", {"sol_from": 0, "sol_to": MAX_SOLS}, 422, "at most"),
        ("channels/hga_margin_deg", {"sol_from": -1}, 422, "sol_from"),
        ("channels/hga_margin_deg", {"sol_from": "x"}, 422, "sol_from"),
        ("channels/hga_margin_deg", {"max_points": 3}, 422, "max_points"),
        ("channels/hga_margin_deg", {"max_points": MAX_POINTS + 1}, 422, "max_points"),
    ],
)
def test_bad_requests_are_refused_naming_the_problem(
    client: TestClient, path: str, params: dict[str, Any], status: int, says: str
) -> None:
    r = client.get(f"/api/rovers/spirit/{path}", params=params)
    assert r.status_code == status, r.text
    assert says in r.text
    assert client.get("/api/rovers/curiosity/channels").status_code == 404


def test_a_sol_without_telemetry_is_an_empty_series(client: TestClient) -> None:
    sol = client.get("/api/rovers/spirit/sols").json()[-1]
    got = client.get(
        "/api/rovers/spirit/channels/tilt_est_deg", params={"sol_from": sol + 1}
    ).json()
    assert got["frames"] == 0 and got["values"] == [] and got["t_s"] == []


def test_each_command_is_a_notice_as_the_timeline_lists_it(client: TestClient) -> None:
    # at 100x the clock keeps moving after the command: frames keep coming, so a missing
    # notice ends the loop (at 10 frames a second) rather than blocking the test
    clock = {"action": "resume", "speed": 100}
    with client.websocket_connect("/ws/rovers/spirit/telemetry") as ws:
        client.post("/api/rovers/spirit/clock", json=clock, headers=AUTH)
        r = client.post(
            "/api/rovers/spirit/commands", json={"command": "NADIR_UPDATE"}, headers=AUTH
        )
        assert r.status_code == 201, r.text
        seq = r.json()["id"]
        message: dict[str, Any] = {}
        for _ in range(300):
            message = ws.receive_json()
            if message.get("type") == "command":
                break
        client.post("/api/rovers/spirit/clock", json={"action": "pause"}, headers=AUTH)
    assert message.get("type") == "command", "no command notice"
    notice = message["command"]
    assert notice["sequence_id"] == seq and notice["command"] == "NADIR_UPDATE"
    assert notice["submitted_by"] == "bootstrap"
    sol = client.get("/api/rovers/spirit/sols").json()[-1]
    listed = client.get(f"/api/rovers/spirit/sols/{sol}/timeline").json()["commands"]
    assert notice == next(c for c in listed if c["id"] == notice["id"])
