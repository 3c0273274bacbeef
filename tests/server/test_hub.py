"""The hub's two channels (``server.hub``): frames are decimated to the newest, notices
never are, go first, and a client too far behind is told how many it lost."""

from __future__ import annotations

import asyncio

from server.hub import QUEUE_NOTICES, TelemetryHub, next_message
from server.notices import AlarmNotice, CommandNotice, EventNotice, QueueNotice
from server.sinks import FrameBatch
from tests.frame_batches import batch

EV_A = {"text": "a", "kind": "site", "severity": "info"}
EV_B = {"text": "b", "kind": "nadir", "severity": "error"}


def _run(coro):  # type: ignore[no-untyped-def]
    return asyncio.run(coro)


def test_notices_go_before_frames_and_frames_are_merged_to_the_newest() -> None:
    async def scenario() -> list[dict]:  # type: ignore[type-arg]
        hub = TelemetryHub()
        client = hub.subscribe("spirit")
        hub.publish(
            "spirit", batch([{"t_s": 1.0, "events": [EV_A]}, {"t_s": 2.0, "events": [EV_B]}])
        )
        hub.notify("spirit", CommandNotice({"command": "DRIVE_STRAIGHT"}))
        await asyncio.sleep(0)  # let call_soon_threadsafe deliver
        return [await next_message(client), await next_message(client)]

    notice, frame = _run(scenario())
    assert notice["type"] == "command" and notice["dropped_notices"] == 0
    assert frame["t_s"] == 2.0 and [e["text"] for e in frame["events"]] == ["a", "b"]
    assert "type" not in frame


def test_each_merged_event_keeps_the_time_of_its_own_frame() -> None:
    """Issue 14, item 5: at max speed one message carries the events of the frames it
    skipped; each event keeps its own frame's t_s, sol and LMST, not the message's."""
    frames = [
        {"t_s": 100.0 + i, "sol": 3 + i // 2, "lmst_h": 10.0 + i / 10, "events": [ev]}
        for i, ev in enumerate([EV_A, EV_B, {**EV_A, "text": "c"}])
    ]

    async def scenario() -> dict:  # type: ignore[type-arg]
        hub = TelemetryHub()
        client = hub.subscribe("spirit")
        hub.publish("spirit", batch(frames))
        await asyncio.sleep(0)
        return await next_message(client)

    message = _run(scenario())
    assert message["t_s"] == 102.0  # the newest frame ...
    assert message["events"] == [  # ... with every event at its own time
        {"text": "a", "kind": "site", "severity": "info", "t_s": 100.0, "sol": 3, "lmst_h": 10.0},
        {"text": "b", "kind": "nadir", "severity": "error", "t_s": 101.0, "sol": 3, "lmst_h": 10.1},
        {"text": "c", "kind": "site", "severity": "info", "t_s": 102.0, "sol": 4, "lmst_h": 10.2},
    ]


def test_a_waiting_client_wakes_for_a_notice() -> None:
    async def scenario() -> dict:  # type: ignore[type-arg]
        hub = TelemetryHub()
        client = hub.subscribe("spirit")
        waiter = asyncio.create_task(next_message(client))
        await asyncio.sleep(0.01)
        assert not waiter.done()
        hub.notify("spirit", AlarmNotice({"id": 1}))
        return await asyncio.wait_for(waiter, 2.0)

    assert _run(scenario())["alarm"]["id"] == 1


def test_a_client_far_behind_loses_the_oldest_notices_and_is_told() -> None:
    async def scenario() -> dict:  # type: ignore[type-arg]
        hub = TelemetryHub()
        client = hub.subscribe("spirit")
        for i in range(QUEUE_NOTICES + 5):
            hub.notify("spirit", QueueNotice("spirit", [{"i": i}]))
        await asyncio.sleep(0)
        return await next_message(client)

    first = _run(scenario())
    assert first["queue"] == [{"i": 5}] and first["dropped_notices"] == 5


class _Collect:
    """A frame sink beside the hub: every frame the runtime published, in order."""

    def __init__(self) -> None:
        self.frames: list[dict] = []  # type: ignore[type-arg]

    def publish(self, rover: str, batch: FrameBatch) -> None:
        self.frames.extend(batch.downlink)  # the rover's events are the downlink's


VO_DRIVE = "SEQUENCE vo_drive\nNADIR_UPDATE\nDRIVE_STRAIGHT distance_m=4.0 vo=on\nPLANT_SITE\n"


def test_at_max_speed_every_event_of_every_frame_reaches_a_client_exactly_once() -> None:
    """Issue 21, "events missing live": at max speed a command's frames are published in
    one batch (a vo=on drive's hundreds), far more than a client's frame queue holds. The
    client, read at the route's MAX_RATE_HZ, receives every event of every published frame,
    once, at its own frame's time; the frames it never saw are counted in ``dropped``."""
    import math
    import threading

    from sequences.language import parse
    from server.hub import MAX_RATE_HZ, QUEUE_FRAMES
    from server.runtime import ROVERS, RoverRuntime

    runtime = RoverRuntime(ROVERS["spirit"])
    runtime.set_clock(speed=math.inf)
    published = _Collect()
    hub = TelemetryHub()
    runtime.sinks.extend([published, hub])

    def run_queue_out() -> None:  # the clock thread's ticks, until the queue is done
        runtime.enqueue(1, parse(VO_DRIVE))
        for _ in range(200):
            if not runtime.queue and not runtime._playout:
                return
            runtime._tick(0.05)
        raise AssertionError("the sequence did not end")

    async def scenario() -> tuple[list[dict], int]:  # type: ignore[type-arg]
        client = hub.subscribe("spirit")
        ticker = threading.Thread(target=run_queue_out)
        ticker.start()
        received: list[dict] = []  # type: ignore[type-arg]
        dropped = 0
        while ticker.is_alive() or not client.queue.empty():
            try:
                message = await asyncio.wait_for(next_message(client), 0.5)
            except TimeoutError:
                continue
            received.extend(message["events"])
            dropped = message["dropped"]
            await asyncio.sleep(1.0 / MAX_RATE_HZ)  # the route's pacing (server.api.telemetry)
        ticker.join()
        return received, dropped

    received, dropped = _run(scenario())
    sent = [
        {**e, "t_s": f["t_s"], "sol": f["sol"], "lmst_h": f["lmst_h"]}
        for f in published.frames
        for e in f["events"]
    ]
    assert len(published.frames) > QUEUE_FRAMES  # the batch overflowed the client's queue ...
    assert dropped > 0  # ... and frames were dropped
    assert any(e["text"].startswith("VO step 1/") for e in sent)
    key = lambda e: (e["t_s"], e["text"], e["kind"], e["severity"], e["sol"], e["lmst_h"])  # noqa: E731
    assert sorted(map(key, received)) == sorted(map(key, sent))  # every one, exactly once


def test_a_client_outside_the_truth_view_gets_the_downlink_and_no_truth_notice() -> None:
    """Issue 21, item 3: the truth merged in only for a client in the truth view, decided
    when it subscribes; an alarm on a truth channel (and its event) only to such clients."""
    truth_alarm = AlarmNotice({"id": 1, "channel": "hga_margin_deg", "truth": True})
    truth_event = EventNotice({
        "text": "alarm raised: hga_margin_deg -1 deg (truth view)", "kind": "alarm",
        "severity": "error"})  # fmt: skip
    rover_alarm = AlarmNotice({"id": 2, "channel": "aqf", "truth": False})

    async def scenario() -> tuple[list[dict], list[dict]]:  # type: ignore[type-arg]
        hub = TelemetryHub()
        ground, conductor = hub.subscribe("spirit", truth=False), hub.subscribe("spirit")
        hub.publish("spirit", batch([{"t_s": 1.0, "aqf": "Fine", "position_error_m": 0.2}]))
        for notice in (truth_alarm, truth_event, rover_alarm):
            hub.notify("spirit", notice)
        await asyncio.sleep(0)
        got_ground = [await next_message(ground) for _ in range(2)]
        got_conductor = [await next_message(conductor) for _ in range(4)]
        return got_ground, got_conductor

    ground, conductor = _run(scenario())
    assert [m.get("type") for m in ground] == ["alarm", None]
    assert ground[0]["alarm"]["id"] == 2
    assert ground[1]["aqf"] == "Fine" and "position_error_m" not in ground[1]
    assert [m.get("type") for m in conductor] == ["alarm", "event", "alarm", None]
    assert conductor[3]["position_error_m"] == 0.2


def test_across_light_time_the_ground_gets_the_downlink_late_and_the_truth_view_live() -> None:
    """Batches of one record (``server.comm``): a client outside the truth view gets only the
    downlink, when it arrives, stamped ``received_t_s``; older records a pass fills in go to
    no one but their events do; the truth view's frames are the newest downlink with the
    newest truth (``truth_t_s``)."""
    frames = [{"t_s": float(t), "position_error_m": 0.1 * t, "events": []} for t in range(1, 6)]
    frames[1]["events"] = [EV_A]
    whole = batch(frames)

    async def scenario() -> tuple[list[dict], list[dict]]:  # type: ignore[type-arg]
        hub = TelemetryHub()
        ground, truth = hub.subscribe("spirit", truth=False), hub.subscribe("spirit", truth=True)
        hub.publish("spirit", FrameBatch([], whole.truth))  # live: nothing on the ground yet
        await asyncio.sleep(0)
        assert ground.queue.empty() and truth.queue.empty()
        hub.publish("spirit", FrameBatch(whole.downlink[3:], [], 900.0))
        await asyncio.sleep(0)
        got = [await next_message(ground)], [await next_message(truth)]
        hub.publish("spirit", FrameBatch(whole.downlink[:3], [], 950.0))  # filled in
        await asyncio.sleep(0)
        assert ground.queue.empty()  # nothing older than what was shown ...
        got[0].append(dict(ground.events[0]))  # ... but its event goes on
        return got

    ground, truth = _run(scenario())
    assert ground[0]["t_s"] == 5.0 and ground[0]["received_t_s"] == 900.0
    assert "position_error_m" not in ground[0] and "truth_t_s" not in ground[0]
    assert truth[0]["t_s"] == 5.0 and truth[0]["truth_t_s"] == 5.0
    assert truth[0]["position_error_m"] == 0.5
    assert ground[1]["text"] == "a" and ground[1]["t_s"] == 2.0
