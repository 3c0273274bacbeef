"""The truth is a permission (issue 21, item 3): with ``--truth-view conductor`` no one below
the conductor role receives a truth figure anywhere; with ``everyone`` everyone does.

The acceptance crawler serves the console (uvicorn, the 3D view on), drives Spirit at a
high speed for 30 simulated seconds while a viewer, an operator, a conductor and an
anonymous reader each follow both WebSockets (the telemetry one and the 3D view's), then
reads as each of them every GET route of the OpenAPI document, its path parameters filled
with real values (the rovers, a sol with data, every channel, the sequence of the drive),
and the telemetry as CSV. In all that it looks for the truth record's field names
(``truth_schema()``'s properties but ``t_s``, ``events`` and ``estimators``) and for the
true mission positions of the drive (read from the conductor's telemetry, written as JSON
writes them). A tight limit on ``position_error_m``, set by the conductor, makes sure a
truth alarm, its events and its notices exist to be hidden; a gyro bias fault the conductor
injects before the drive (``server.faults``) is looked for by its parameter, which no one
below the truth view may be told of.
"""

from __future__ import annotations

import contextlib
import json
import re
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import httpx
import pytest
import uvicorn
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from server.access.truth_view import check_truth_view, may_see_truth
from server.app import ServerConfig, create_app, data_dir_url
from server.state import Server
from sim.scoring.truth import truth_schema
from tests.server.test_server_restart import _free_port
from tests.viser_wire import WireViewer

BOOTSTRAP = "truth-view-bootstrap"
ROVER = "spirit"
DRIVE_S = 30.0  # simulated seconds of the drive the WebSockets follow
SPEED = 50.0  # the drive's 30 s in well under a wall second of simulation
FAULT_BIAS = 12.3456  # the injected fault's parameter: its mark wherever it is shown
FAULT_MARK = "bias step +12.3456"
TRUTH_NAMES = sorted(set(truth_schema()["properties"]) - {"t_s", "events", "estimators"})
ROLES = ("anonymous", "viewer", "operator", "conductor")
WAIT_S = 120.0  # a condition waited for on a busy machine; never a fixed sleep


def wait_for(predicate: Any, what: str, timeout_s: float = WAIT_S) -> Any:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"timed out waiting for {what}")


def truth_found(text: str, positions: set[str]) -> set[str]:
    """The truth field names (as a JSON key or CSV column, a side estimator's included) and
    true position values (as JSON writes them) that ``text`` holds."""
    names = {n for n in TRUTH_NAMES if re.search(rf"(?<![A-Za-z0-9]){n}(?![A-Za-z])", text)}
    numbers = set(re.findall(r"-?\d+\.\d+(?:e-?\d+)?", text))
    return names | (positions & numbers)


class TelemetrySocket:
    """The telemetry WebSocket of one reader: every message it receives, as text."""

    def __init__(self, url: str, token: str | None) -> None:
        headers = {"Authorization": f"Bearer {token}"} if token else None
        self.messages: list[str] = []
        self._ws: ClientConnection = connect(url, additional_headers=headers, proxy=None)
        self._thread = threading.Thread(target=self._drain, daemon=True)
        self._thread.start()

    def _drain(self) -> None:
        with contextlib.suppress(ConnectionClosed):
            for data in self._ws:
                self.messages.append(data if isinstance(data, str) else data.decode())

    def frames(self) -> int:
        return sum(1 for m in self.messages if '"type"' not in m[:12])

    def close(self) -> None:
        self._ws.close()
        self._thread.join(timeout=10.0)


def scene_text(viewer: WireViewer) -> str:
    """The 3D view's scene messages as JSON text (binary buffers left out)."""
    with viewer._lock:
        messages = list(viewer.messages)
    return json.dumps(messages, default=lambda _: None)


@dataclass
class Crawl:
    """What each reader received, as text, by where it came from."""

    truth_view: str
    positions: set[str]  # the true mission positions of the drive, as JSON writes them
    received: dict[str, dict[str, str]] = field(default_factory=dict)  # role -> where -> text
    tokens: dict[str, str | None] = field(default_factory=dict)
    scene_nodes: dict[str, set[str]] = field(default_factory=dict)  # role -> node names


def _get_routes(base: str) -> list[str]:
    """Every GET path of the OpenAPI document."""
    schema = httpx.get(f"{base}/openapi.json", timeout=30).json()
    return [p for p, ops in schema["paths"].items() if "get" in ops]


def _fill(path: str, values: dict[str, list[str]]) -> list[str]:
    """``path`` with each of its parameters filled, once per value of the one that varies."""
    out = [path]
    for name, options in values.items():
        if "{" + name + "}" in path:
            out = [p.replace("{" + name + "}", v) for p in out for v in options]
    assert not any("{" in p for p in out), f"no value for a parameter of {path}"
    return out


@contextlib.contextmanager
def _serve(config: ServerConfig) -> Iterator[tuple[str, Server]]:
    app = create_app(config)
    port = _free_port()
    server = uvicorn.Server(uvicorn.Config(app, port=port, log_level="warning", lifespan="on"))
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    try:
        wait_for(lambda: server.started, "the server to start")
        yield f"127.0.0.1:{port}", app.state.server
    finally:
        server.should_exit = True
        thread.join(timeout=60)


def crawl(tmp_path: Any, truth_view: str) -> Iterator[Crawl]:
    config = ServerConfig(
        database_url=data_dir_url(tmp_path),
        operator_token=BOOTSTRAP,
        viewer_3d=True,
        truth_view=truth_view,
        validation_processes=0,
    )
    with _serve(config) as (host, server):
        base = f"http://{host}"
        tokens: dict[str, str | None] = {"anonymous": None}
        for role in ROLES[1:]:
            tokens[role] = server.accounts.add_user(f"{role}_user", role).token
        boot = {"Authorization": f"Bearer {BOOTSTRAP}"}
        conductor = {"Authorization": f"Bearer {tokens['conductor']}"}
        # a truth alarm to hide: the position error passes 1 mm as soon as the rover drives
        answer = httpx.put(
            f"{base}/api/rovers/{ROVER}/limits/position_error_m",
            json={"warning": 0.001, "critical": 0.002},
            headers=conductor,
        )
        assert answer.status_code == 200, answer.text
        # a fault to hide (server.faults): injected now, applied as the drive starts
        fault = {"kind": "gyro_bias", "parameters": {"axis": "z", "bias_deg_per_h": FAULT_BIAS}}
        answer = httpx.post(f"{base}/api/rovers/{ROVER}/faults", json=fault, headers=conductor)
        assert answer.status_code == 201, answer.text
        sockets = {
            role: TelemetrySocket(f"ws://{host}/ws/rovers/{ROVER}/telemetry", token)
            for role, token in tokens.items()
        }
        scenes = {
            role: WireViewer(
                f"ws://{host}/viser/{ROVER}",
                {"Authorization": f"Bearer {token}"} if token else None,
            )
            for role, token in tokens.items()
        }
        for v in scenes.values():
            wait_for(lambda v=v: v.status(), "the 3D view's controls")
        start_t_s = httpx.get(f"{base}/api/rovers/{ROVER}/state", headers=boot).json()["t_s"]
        assert (
            httpx.post(
                f"{base}/api/rovers/{ROVER}/clock", json={"speed": SPEED}, headers=boot
            ).status_code
            == 200
        )
        drive = {"command": "DRIVE_STRAIGHT", "args": {"distance_m": 3.0}}
        answer = httpx.post(f"{base}/api/rovers/{ROVER}/commands", json=drive, headers=boot)
        assert answer.status_code == 201, answer.text

        def driven() -> bool:
            state = httpx.get(f"{base}/api/rovers/{ROVER}/state", headers=boot).json()
            return bool(state["t_s"] >= start_t_s + DRIVE_S)

        wait_for(driven, "30 s of the drive")
        httpx.post(f"{base}/api/rovers/{ROVER}/clock", json={"action": "pause"}, headers=boot)
        for s in sockets.values():
            wait_for(lambda s=s: s.frames() >= 3, "frames on each telemetry WebSocket")
        frames = httpx.get(f"{base}/api/rovers/{ROVER}/telemetry", headers=conductor).json()
        moved = [f["p_mission_true"] for f in frames if abs(f["p_mission_true"][0]) > 0.05]
        assert len(moved) > 10, "the rover drove"
        positions = {json.dumps(v) for p in moved for v in p}
        # the 3D views have drawn the drive (the live rover moved off its start)
        for v in scenes.values():
            wait_for(lambda v=v: abs((v.position("/rover") or (0.0,))[0]) > 0.05, "a drawn drive")
        result = Crawl(truth_view, positions, tokens=tokens)
        sols = httpx.get(f"{base}/api/rovers/{ROVER}/sols", headers=boot).json()
        channels = httpx.get(f"{base}/api/rovers/{ROVER}/channels", headers=conductor).json()
        values = {
            "rover": ["spirit", "opportunity"],
            "sol": [str(sols[-1])],
            "channel": [c["name"] for c in channels],
            "sequence_id": ["1"],
            "image_id": ["1"],
            "rehearsal_id": ["1"],  # none run here: the report's truth is tested apart
        }
        paths = [p for route in _get_routes(base) for p in _fill(route, values)]
        for role, token in tokens.items():
            headers = {"Authorization": f"Bearer {token}"} if token else {}
            got = result.received.setdefault(role, {})
            with httpx.Client(base_url=base, headers=headers, timeout=60) as client:
                for path in paths:
                    got[path] = client.get(path).text
                got["telemetry as CSV"] = client.get(
                    f"/api/rovers/{ROVER}/telemetry", headers={"Accept": "text/csv"}
                ).text
            got["the telemetry WebSocket"] = "\n".join(sockets[role].messages)
            got["the 3D view's WebSocket"] = scene_text(scenes[role])
            with scenes[role]._lock:
                result.scene_nodes[role] = {n for _, n in scenes[role].nodes}
        for s in sockets.values():
            s.close()
        for v in scenes.values():
            v.close()
        yield result


@pytest.fixture(scope="module", params=["conductor", "everyone"])
def crawled(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Any:
    yield from crawl(tmp_path_factory.mktemp(f"truth_{request.param}"), request.param)


def _sees(crawled: Crawl, role: str) -> bool:
    return crawled.truth_view == "everyone" or role == "conductor"


@pytest.mark.parametrize("role", ROLES)
def test_the_truth_reaches_only_the_truth_view(crawled: Crawl, role: str) -> None:
    got = crawled.received[role]
    found = {where: truth_found(text, crawled.positions) for where, text in got.items()}
    if not _sees(crawled, role):
        leaks = {where: sorted(f)[:5] for where, f in found.items() if f}
        assert not leaks, f"{role} received the truth under --truth-view conductor: {leaks}"
        told = [where for where, text in got.items() if "12.3456" in text]
        assert not told, f"{role} was told of the unrevealed fault: {told}"
        return
    # the fault is the truth view's: its truth event (the timeline) and the conductor's list
    assert any(FAULT_MARK in text for text in got.values()), f"{role}: the fault nowhere"
    # in the truth view: every truth field name, and the true positions, everywhere they go
    union = set().union(*found.values())
    assert set(TRUTH_NAMES) <= union, set(TRUTH_NAMES) - union
    for where in ("the telemetry WebSocket", "the 3D view's WebSocket", "telemetry as CSV"):
        assert found[where] & crawled.positions, f"{role}: no true position in {where}"
    assert set(TRUTH_NAMES) <= found["the telemetry WebSocket"]
    assert set(TRUTH_NAMES) <= found[f"/api/rovers/{ROVER}/telemetry"]


@pytest.mark.parametrize("role", ROLES)
def test_the_truth_layer_of_the_3d_view_exists_only_in_the_truth_view(
    crawled: Crawl, role: str
) -> None:
    nodes = crawled.scene_nodes[role]
    truth_layer = {"/ghost", "/sun", "/earth", "/hga"}
    truth_layer |= {n for n in nodes if n.startswith("/traverse_true")}
    assert "/rover" in nodes and any(n.startswith("/traverse_est") for n in nodes)
    if _sees(crawled, role):
        assert {"/ghost", "/sun", "/earth", "/hga"} <= nodes
        assert any(n.startswith("/traverse_true") for n in nodes)
    else:
        assert not nodes & truth_layer


@pytest.mark.parametrize("role", ROLES)
def test_a_truth_channel_is_refused_naming_the_permission(crawled: Crawl, role: str) -> None:
    answer = crawled.received[role][f"/api/rovers/{ROVER}/channels/position_error_m"]
    if _sees(crawled, role):
        assert json.loads(answer)["name"] == "position_error_m"
    else:
        assert "conductor role" in json.loads(answer)["detail"]
        listed = json.loads(crawled.received[role][f"/api/rovers/{ROVER}/channels"])
        assert listed and not any(c["truth"] for c in listed)


def test_the_crawler_finds_a_truth_field_where_one_is_planted() -> None:
    frame = {"t_s": 1.0, "p_mission_est": [1.25, 0.5, 0.0], "aqf": "Fine"}
    assert not truth_found(json.dumps(frame), {"1.2345678"})
    assert truth_found(json.dumps({**frame, "hga_margin_deg": 1.0}), set()) == {"hga_margin_deg"}
    assert truth_found("t_s,kinematic_ekf_position_error_m\n", set()) == {"position_error_m"}
    assert truth_found(json.dumps({**frame, "p": [1.2345678]}), {"1.2345678"}) == {"1.2345678"}


def test_a_wrong_truth_view_is_refused_naming_it() -> None:
    with pytest.raises(ValueError, match="truth_view must be one of everyone, conductor"):
        check_truth_view("operators")
    with pytest.raises(ValueError, match="truth_view"):
        ServerConfig(database_url="sqlite://", truth_view="all")


def test_the_truth_view_follows_the_role() -> None:
    from server.access.accounts import ANONYMOUS, Principal

    for role in ("viewer", "operator", "conductor", "admin"):
        who = Principal("x", role)  # type: ignore[arg-type]
        assert may_see_truth("everyone", who)
        assert may_see_truth("conductor", who) == (role in ("conductor", "admin"))
    assert may_see_truth("everyone", ANONYMOUS) and not may_see_truth("conductor", ANONYMOUS)


@pytest.mark.parametrize("role", ROLES)
def test_a_truth_alarm_its_events_and_notices_are_the_truth_view_s(
    crawled: Crawl, role: str
) -> None:
    got = crawled.received[role]
    alarms = json.loads(got[f"/api/rovers/{ROVER}/alarms"])
    events = json.loads(got[f"/api/rovers/{ROVER}/events"])["events"]
    sols = json.loads(got[f"/api/rovers/{ROVER}/sols"])
    timeline = json.loads(got[f"/api/rovers/{ROVER}/sols/{sols[-1]}/timeline"])
    notices = [json.loads(m) for m in got["the telemetry WebSocket"].split("\n") if '"type"' in m]
    raised = [a for a in alarms if a["channel"] == "position_error_m"]
    said = [e for e in events if "position_error_m" in e["text"]]
    pushed = [n for n in notices if n["type"] == "alarm" and n["alarm"]["truth"]]
    if _sees(crawled, role):
        assert raised and said and pushed and "truth" in timeline
        assert any(a["channel"] == "position_error_m" for a in timeline["alarms"])
    else:
        assert not raised and not said and not pushed and "truth" not in timeline
        assert not any(a["truth"] for a in alarms + timeline["alarms"])
