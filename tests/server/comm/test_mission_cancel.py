"""A cancel across light time is itself a command that goes up: one that reaches the rover
after the sequence has finished finds nothing to cancel, and the ground hears so; one that
arrives in time stops the sequence onboard, and the ground hears where."""

from __future__ import annotations

import math

from server.comm.hosting import CancelSent
from server.state import Server
from tests.server.comm.conftest import stages, tick_until, upload


def events(server: Server) -> list[str]:
    server.writer.flush()
    return [e["text"] for e in server.store.events("spirit", -math.inf, math.inf)]


def test_a_cancel_that_arrives_after_the_sequence_ended_finds_nothing(server: Server) -> None:
    runtime = server.rovers["spirit"]
    runtime.set_clock(speed=math.inf)
    # an 8 h wait: the ground hears it is onboard (a pass the same morning) while it runs,
    # and the next uplink window (the next morning) comes after it has ended
    seq_id = upload(server, "SEQUENCE day\nWAIT duration_s=30000\n")
    tick_until(runtime, lambda: "received" in stages(server, seq_id), "the rover's receipt")
    assert "completed" not in stages(server, seq_id)
    sent = runtime.cancel(seq_id)
    assert isinstance(sent, CancelSent)  # it is onboard: the ground cannot drop it
    assert "cancel accepted" in stages(server, seq_id)
    tick_until(runtime, lambda: any("reached the rover after" in e for e in events(server)),
               "the rover's word that there was nothing to cancel")  # fmt: skip
    got = server.store.get_sequence(seq_id)
    assert got is not None and got["status"] == "completed"
    history = stages(server, seq_id)
    assert history.index("completed") < len(history) and "cancel radiated" in history
    assert "cancelled" not in history
    assert runtime.cancel(seq_id) is None  # ended, as the ground knows: nothing to cancel


def test_a_cancel_radiated_in_the_same_window_stops_it_before_it_starts(server: Server) -> None:
    runtime = server.rovers["spirit"]
    runtime.set_clock(speed=math.inf)
    seq_id = upload(server, "SEQUENCE quick\nNADIR_UPDATE\n")
    tick_until(runtime, lambda: "radiated" in stages(server, seq_id), "the sequence radiated")
    assert isinstance(runtime.cancel(seq_id), CancelSent)  # the window is still open
    tick_until(runtime, lambda: (server.store.get_sequence(seq_id) or {}).get("status")
               == "cancelled", "the rover's report of the cancel")  # fmt: skip
    got = server.store.get_sequence(seq_id)
    assert got is not None and "before it started" in (got["detail"] or "")
    assert not [c for c in server.store.commands("spirit", -math.inf, math.inf)
                if c["sequence_id"] == seq_id]  # fmt: skip


def test_a_cancel_that_arrives_while_it_runs_stops_it_there(server: Server) -> None:
    runtime = server.rovers["spirit"]
    # at a finite speed a long WAIT runs a chunk at a time, and the ground follows it (at
    # max speed the whole wait and its play-out go by in one tick, the ground's clock too)
    runtime.set_clock(speed=10_000.0)
    # a wait of 1.7 sols keeps the sequence running past the next uplink window
    seq_id = upload(server, "SEQUENCE long\nWAIT duration_s=150000\nNADIR_UPDATE\n")
    tick_until(runtime, lambda: "received" in stages(server, seq_id), "the rover's receipt")
    assert isinstance(runtime.cancel(seq_id), CancelSent)
    tick_until(runtime, lambda: (server.store.get_sequence(seq_id) or {}).get("status")
               == "cancelled", "the rover's report of the cancel")  # fmt: skip
    got = server.store.get_sequence(seq_id)
    assert got is not None and "during step 1 of 2" in (got["detail"] or "")
    assert "cancelled" in stages(server, seq_id)
    # the step after the wait never ran (the wait, cut where it was, reports no row)
    commands = server.store.commands("spirit", -math.inf, math.inf)
    assert not [c for c in commands if c["sequence_id"] == seq_id]
