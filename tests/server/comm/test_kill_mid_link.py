"""Two defects ``roverops bench comm`` found by killing a ``--comm mission`` server, each
reproduced here without a kill: a server's writes that a SIGKILL loses (the writer's queue,
never flushed) are simply not flushed, and the restart is a second ``Server`` on the same
database.

1. A sequence's status was committed at once but its event ("sequence #N ... completed")
   waited in the writer; a restart delivered the status again, found it stored and made no
   event: the event was lost for good. Now the event is flushed with the status, and a
   status delivered again adds its event if storage lacks it (``Server.sequence_status``).
2. An uplink that reached the rover changed the queue, and the queue change was applied to
   the last checkpoint, whose link still had the uplink on its way up: restored from it, the
   rover had the sequence queued and the link delivered it again, so it ran twice. Now what
   the link hands onboard waits for the clock thread's own checkpoint (``by_link``).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from sequences.validate import validate
from server.state import Server, ServerConfig
from server.storage.engine import data_dir_url
from sim.comm.windows import comm_windows
from sim.world.marsclock import get_mission

DRIVE = "SEQUENCE short_drive\nDRIVE_STRAIGHT distance_m=1\n"


def _config(data_dir: Path, comm: str = "instant") -> ServerConfig:
    return ServerConfig(
        database_url=data_dir_url(data_dir),
        start_clocks=False,
        comm=comm,
        validation_processes=0,
    )


@pytest.fixture
def servers() -> Iterator[list[Server]]:
    """The servers a test opens, their stores closed at the end (their writers never
    flushed: a killed server's are not)."""
    opened: list[Server] = []
    yield opened
    for server in opened:
        server.store.close()


def _upload(server: Server, text: str) -> int:
    result = validate(text)
    assert result.sequence is not None
    seq_id = server.store.add_sequence("spirit", "s", text, "text", "queued", [], [], [])
    server.rovers["spirit"].enqueue(seq_id, result.sequence)
    return seq_id


def test_a_status_delivered_again_after_a_kill_keeps_its_event(
    tmp_path: Path, servers: list[Server]
) -> None:
    first = Server.open(_config(tmp_path))
    servers.append(first)
    seq_id = first.store.add_sequence("spirit", "s", DRIVE, "text", "running", [], [], [])
    first.sequence_status(seq_id, "completed", None)  # the report came down
    # killed now: the event waits in the writer's queue and is never written
    again = Server.open(_config(tmp_path))
    servers.append(again)
    again.sequence_status(seq_id, "completed", None)  # the report comes down again
    again.writer.flush()
    texts = [e["text"] for e in again.store.events("spirit", -math.inf, math.inf)]
    assert f"sequence #{seq_id} s completed" in texts


def test_an_uplink_on_board_before_a_kill_is_queued_once(
    tmp_path: Path, servers: list[Server]
) -> None:
    first = Server.open(_config(tmp_path, "mission"))
    servers.append(first)
    runtime = first.rovers["spirit"]
    seq_id = _upload(first, DRIVE)
    site = get_mission("spirit")
    t0 = runtime.t_s
    windows = comm_windows(site.lat_deg, site.lon_east_deg, runtime.comm.plan, t0, t0 + 90_000)
    window = next(w for w in windows if w.kind == "uplink")
    runtime.comm.advance(window.start_t_s + 60.0)  # radiated: on its way up
    mission = runtime.comm.mission
    assert mission is not None and [u.sequence_id for u in mission.link.rising] == [seq_id]
    arrival = mission.link.rising[0].arrival_t_s
    assert arrival is not None
    runtime.checkpoint()  # the clock thread's last checkpoint before the arrival
    runtime.comm.advance(arrival + 1.0)  # onboard: the queue change saved at once
    assert [q.sequence_id for q in runtime.queue] == [seq_id]
    first.writer.flush()  # written; killed before the clock thread's next checkpoint
    again = Server.open(_config(tmp_path, "mission"))
    servers.append(again)
    restored = again.rovers["spirit"]
    restored.comm.advance(arrival + 1.0)
    assert [q.sequence_id for q in restored.queue] == [seq_id]
