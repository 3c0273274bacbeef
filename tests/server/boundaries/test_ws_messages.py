"""The WebSocket's messages are a tagged union published in the schema (issue 21, item 5):
every message a real server sends while a sequence runs (frames, and the command, event and
queue notices) validates against ``GET /api/schema/ws``'s union."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from typing import Any

import pytest
from fastapi.testclient import TestClient

from server.api.telemetry import WS_MESSAGE
from server.app import ServerConfig, create_app, data_dir_url

TOKEN = "ws-schema-test-token"
AUTH = {"Authorization": f"Bearer {TOKEN}"}
SEQUENCE = "SEQUENCE ws\nWAIT duration_s=20\nGET_FINE_ATTITUDE\n"
KINDS = {"frame", "command", "event", "queue"}


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[TestClient, list[Any]]]:
    """The app, and the WebSocket messages received while a sequence ran to its end."""
    url = data_dir_url(tmp_path_factory.mktemp("ws"))
    with TestClient(create_app(ServerConfig(database_url=url, operator_token=TOKEN))) as client:
        messages: list[dict[str, Any]] = []
        with client.websocket_connect("/ws/rovers/spirit/telemetry") as ws:

            def ended() -> bool:
                commands = [m for m in messages if m.get("type") == "command"]
                kinds = {m.get("type", "frame") for m in messages}
                return len(commands) >= 2 and kinds >= KINDS

            def read() -> None:
                while not ended():
                    messages.append(ws.receive_json())

            reader = threading.Thread(target=read, daemon=True)
            reader.start()
            client.post("/api/rovers/spirit/clock", json={"speed": "max"}, headers=AUTH)
            r = client.post("/api/rovers/spirit/sequences", content=SEQUENCE, headers=AUTH)
            assert r.status_code == 201, r.text
            reader.join(timeout=120.0)
            assert not reader.is_alive(), f"kinds seen: {sorted({m.get('type') for m in messages})}"
        client.post("/api/rovers/spirit/clock", json={"action": "pause"}, headers=AUTH)
        yield client, messages


def test_the_schema_route_publishes_the_union(run: tuple[TestClient, list[Any]]) -> None:
    client, _ = run
    r = client.get("/api/schema/ws")
    assert r.status_code == 200, r.text
    schema = r.json()
    assert schema == WS_MESSAGE.json_schema()
    titles = {d.get("title") for d in schema["$defs"].values()}
    assert {"FrameMessage", "AlarmMessage", "CommandMessage", "EventMessage"} <= titles
    assert "QueueMessage" in titles and len(schema["oneOf"]) == 5


def test_every_message_the_hub_sent_validates(run: tuple[TestClient, list[Any]]) -> None:
    _, messages = run
    for message in messages:
        parsed = WS_MESSAGE.validate_python(message)
        assert getattr(parsed, "type", "frame") == message.get("type", "frame")
    commands = [m["command"] for m in messages if m.get("type") == "command"]
    assert [c["command"].split()[0] for c in commands[:2]] == ["WAIT", "GET_FINE_ATTITUDE"]


def test_a_message_off_the_union_is_refused() -> None:
    with pytest.raises(ValueError, match="queue"):
        WS_MESSAGE.validate_python({"type": "queue", "dropped_notices": 0, "rover": "spirit"})
    with pytest.raises(ValueError, match="does not match any of the expected tags"):
        WS_MESSAGE.validate_python({"type": "telemetry", "dropped_notices": 0})
