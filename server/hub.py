"""Live telemetry fan-out: frames from the rover threads to WebSocket clients.

Each client has its own bounded queue. The rover thread never waits: a full queue drops
its oldest frame (``put_frames``), so a slow client loses frames, not the simulation, and
never slows the other clients; it is told how many in ``dropped``. A frame's events do not
go with it: they wait apart (``Client.events``), each stamped with its own frame's ``t_s``,
``sol`` and ``lmst_h`` (``stamped_events``). Each client's sender sends at most
``MAX_RATE_HZ`` frames per wall second: it takes the newest frame waiting and carries every
event waiting, so no event is lost to decimation nor to a full queue (at max speed one
batch is a whole drive's frames, far more than the queue holds), nor shown at the wrong
time. Only a client ``QUEUE_EVENTS`` events behind loses the oldest, and is told how many
in ``dropped_events`` (so it knows to re-read the event log over REST).

Besides frames, the hub carries *notices*: small messages with a ``type`` (``"command"``,
``"alarm"``, ``"queue"``, ...) that say something changed (``notify``). A frame has no
``type``. Notices are never decimated and go before the frames waiting; each client keeps
up to ``QUEUE_NOTICES`` of them (a client that falls further behind loses the oldest and
is told how many in ``dropped_notices``, so it knows to re-read the REST API).

Each client is in the truth view or not (``server.access.truth_view``), decided once when it
subscribes, from its handshake's token: it receives the downlink records merged with their
truth records, or the downlink records alone; the notices that tell the truth (an alarm on
a truth channel and its event) go only to clients in the truth view.

Every frame a client receives carries ``published_wall``: the wall-clock time
(``time.time()``, Unix seconds) at which the hub handed it on, so a client can measure its
latency (``roverops bench server``). The stamp is on the clients' copies only, never on the
frames the storage writer keeps.
"""

from __future__ import annotations

import asyncio
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from server.access.truth_view import is_truth_notice
from server.notices import Notice
from server.sinks import FrameBatch, live_frame
from sim.scoring.truth import TruthDict, merged

MAX_RATE_HZ = 10.0
QUEUE_FRAMES = 64
QUEUE_NOTICES = 1024
QUEUE_EVENTS = 4096  # a sol of 8 Hz activity has a few hundred


@dataclass(eq=False)
class Client:
    """One WebSocket subscriber: its frames, the events of the frames not yet sent, its
    notices, how many of each it lost to a full queue, and whether it sees the truth
    (module docstring)."""

    loop: asyncio.AbstractEventLoop
    truth: bool = True
    queue: asyncio.Queue[dict[str, Any]] = field(
        default_factory=lambda: asyncio.Queue(maxsize=QUEUE_FRAMES)
    )
    dropped: int = 0
    notices: deque[dict[str, Any]] = field(default_factory=deque)
    dropped_notices: int = 0
    events: deque[dict[str, Any]] = field(default_factory=deque)
    dropped_events: int = 0
    wake: asyncio.Event = field(default_factory=asyncio.Event)

    def put_frames(
        self, frames: list[dict[str, Any]], late: list[dict[str, Any]] | None = None
    ) -> None:
        """Enqueue a batch on the client's loop, dropping the oldest frames when full; the
        batch's events wait apart, stamped, so a dropped frame loses none of them. ``late``:
        frames older than the newest sent, whose events alone go on."""
        for frame in late or ():
            self._put_events(frame)
        for frame in frames:
            if self.queue.full():
                self.queue.get_nowait()
                self.dropped += 1
            self.queue.put_nowait(frame)
            self._put_events(frame)
        self.wake.set()

    def _put_events(self, frame: dict[str, Any]) -> None:
        for event in stamped_events(frame):
            if len(self.events) >= QUEUE_EVENTS:
                self.events.popleft()
                self.dropped_events += 1
            self.events.append(event)

    def put_notice(self, notice: dict[str, Any]) -> None:
        """Enqueue a notice on the client's loop, dropping the oldest when full."""
        if len(self.notices) >= QUEUE_NOTICES:
            self.notices.popleft()
            self.dropped_notices += 1
        self.notices.append(notice)
        self.wake.set()


class TelemetryHub:
    """Per-rover sets of clients; ``publish`` is called from the rover threads."""

    def __init__(self) -> None:
        self._clients: dict[str, set[Client]] = {}
        self._lock = threading.Lock()
        # across light time: the newest downlink handed on and the newest truth, per rover
        self._newest: dict[str, dict[str, Any]] = {}
        self._truth: dict[str, TruthDict] = {}

    def subscribe(self, rover: str, truth: bool = True) -> Client:
        """A new client on the running loop, in the truth view if ``truth``."""
        client = Client(asyncio.get_running_loop(), truth)
        with self._lock:
            self._clients.setdefault(rover, set()).add(client)
        return client

    def unsubscribe(self, rover: str, client: Client) -> None:
        """Forget a client."""
        with self._lock:
            self._clients.get(rover, set()).discard(client)

    def count(self, rover: str) -> int:
        """How many clients follow ``rover``."""
        with self._lock:
            return len(self._clients.get(rover, set()))

    def publish(self, rover: str, batch: FrameBatch) -> None:
        """A frame sink (``server.sinks``): hand frames to every client of ``rover``
        (thread-safe, never blocks), each a copy stamped with ``published_wall``: the
        downlink merged with the truth for a client in the truth view, else the downlink.

        Across light time (a batch of one record, ``server.comm``) the downlink comes when
        it reaches the ground, stamped ``received_t_s``; a downlink record older than the
        newest one handed on (a pass filling in) goes to no client, only its events do. The
        truth view sees the truth live: its frames are the newest downlink on the ground
        with the newest truth record merged in, ``truth_t_s`` the truth's own time."""
        now = time.time()
        with self._lock:
            clients = list(self._clients.get(rover, set()))
            if batch.paired:
                ground = [{**d, "published_wall": now} for d in batch.downlink]
                pairs = zip(batch.downlink, batch.truth, strict=True)
                truth = [{**merged(d, t), "published_wall": now} for d, t in pairs]
                late: list[dict[str, Any]] = []
            else:
                ground, late = self._received(rover, batch, now)
                latest = self._truth.get(rover)
                if batch.truth:
                    latest = self._truth[rover] = batch.truth[-1]
                    newest = self._newest.get(rover)
                    ground = []  # nothing new on the ground: the truth view's frame only
                    # its events went with it already
                    truth = [] if newest is None else [_live({**newest, "events": []}, latest, now)]
                else:
                    truth = [_live(d, latest, now) for d in ground] if latest else list(ground)
        for client in clients:
            frames = truth if client.truth else ground
            if not (frames or late):
                continue
            try:
                client.loop.call_soon_threadsafe(client.put_frames, frames, late)
            except RuntimeError:  # the client's loop has closed
                self.unsubscribe(rover, client)

    def _received(
        self, rover: str, batch: FrameBatch, now: float
    ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
        """A batch that reached the ground: its records newer than the newest handed on,
        stamped, and the events of the older ones (the caller holds the lock)."""
        newest = self._newest.get(rover)
        fresh, late = [], []
        for d in sorted(batch.downlink, key=lambda d: d["t_s"]):
            if newest is None or d["t_s"] > newest["t_s"]:
                newest = {**d, "published_wall": now, "received_t_s": batch.received_t_s}
                fresh.append(newest)
            elif d.get("events"):
                late.append(dict(d))
        if newest is not None:
            self._newest[rover] = newest
        return fresh, late

    def notify(self, rover: str, notice: Notice) -> None:
        """Hand a notice (``server.notices``) to every client of ``rover`` (thread-safe,
        never blocks); one that tells the truth to those in the truth view only."""
        message = notice.message()
        truth_only = is_truth_notice(message)
        with self._lock:
            clients = list(self._clients.get(rover, set()))
        for client in clients:
            if truth_only and not client.truth:
                continue
            try:
                client.loop.call_soon_threadsafe(client.put_notice, dict(message))
            except RuntimeError:  # the client's loop has closed
                self.unsubscribe(rover, client)


def _live(downlink: dict[str, Any], truth: TruthDict | None, now: float) -> dict[str, Any]:
    return {**live_frame(downlink, truth), "published_wall": now}


def pending_notice(client: Client) -> dict[str, Any] | None:
    """The oldest notice waiting (stamped with ``dropped_notices``), or ``None``."""
    if not client.notices:
        return None
    return {**client.notices.popleft(), "dropped_notices": client.dropped_notices}


def stamped_events(frame: dict[str, Any]) -> list[dict[str, Any]]:
    """The frame's events, each with the frame's ``t_s``, ``sol`` and ``lmst_h``: a message
    carries the events of the frames it skipped, and each keeps its own time."""
    when = {key: frame.get(key) for key in ("t_s", "sol", "lmst_h")}
    return [{**e, **when} for e in frame.get("events", [])]


async def next_message(client: Client) -> dict[str, Any]:
    """The next message to send: a notice if one waits, else the newest frame with every
    event waiting (those of the frames it skipped or that a full queue dropped)."""
    while True:
        notice = pending_notice(client)
        if notice is not None:
            return notice
        if not client.queue.empty():
            break
        client.wake.clear()
        await client.wake.wait()
    frame = client.queue.get_nowait()
    while not client.queue.empty():
        frame = client.queue.get_nowait()
    out = dict(frame)
    out["events"] = list(client.events)
    client.events.clear()
    out["dropped"] = client.dropped
    out["dropped_events"] = client.dropped_events
    return out
