"""What the comm tests share: a server in mission mode whose clocks the test runs, an upload
straight into a rover, a sequence's stages, and ticking a clock until something holds."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from sequences.validate import validate
from server.runtime import RoverRuntime
from server.state import Server, ServerConfig

MAX_TICKS = 20_000


@pytest.fixture
def server() -> Iterator[Server]:
    """A server of rovers in mission mode on an in-memory database, clocks not started."""
    server = Server.open(ServerConfig(database_url="sqlite://", start_clocks=False, comm="mission"))
    server.start()
    try:
        yield server
    finally:
        server.stop()


def upload(server: Server, text: str, rover: str = "spirit") -> int:
    """Store a valid sequence as accepted and hand it to the rover's runtime; its id."""
    result = validate(text)
    assert result.sequence is not None, result.errors
    seq_id = server.store.add_sequence(rover, "s", text, "text", "queued", [], [], [])
    server.rovers[rover].enqueue(seq_id, result.sequence)
    return seq_id


def stages(server: Server, seq_id: int) -> list[str]:
    """The stages of a sequence's command history, in the order learned."""
    return [s["stage"] for s in (server.store.get_sequence(seq_id) or {}).get("stages") or []]


def tick_until(runtime: RoverRuntime, done: Callable[[], Any], why: str) -> None:
    """The clock a tick at a time (the test looks between ticks), each a quarter of a wall
    second's worth: at max speed a command and its play-out, at 10,000x 2,500 s."""
    for _ in range(MAX_TICKS):
        if done():
            return
        runtime._tick(0.25)
    raise AssertionError(f"never: {why}")
