"""``BatchWriter``: the high-rate writes (frames, events, images, commands, checkpoints)
taken off the simulation threads and committed together at least once per ``interval_s``.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

from sqlalchemy.engine import Connection

from server.storage.images import ImageRows, insert_images
from server.storage.records import CommandRecord, command_row
from server.storage.store import EventRow, FrameRows, Store

if TYPE_CHECKING:
    from sim.loop.images import ImageDict

log = logging.getLogger(__name__)


class BatchWriter:
    """Queue writes from the simulation threads and flush them in one transaction at least
    once per ``interval_s`` (default 0.5 s) of wall time, from its own thread, so the
    simulation never waits on the database. A server killed with SIGKILL loses at most the
    writes of the last interval.

    The queueing methods only append under a lock. A flush writes everything queued when
    it starts, frames, events, commands and the latest checkpoint of each rover together,
    so a checkpoint is never committed without the telemetry queued before it. If that
    transaction fails (say, a command naming an unknown sequence), each kind is retried in
    its own transaction and only a kind that fails again is dropped (and logged), so one
    bad row cannot block telemetry for good. ``flushed_frames`` counts the frames committed.
    The store's reads flush first (``Store.commit_queued_with``), so a reader never sees
    the database behind the writes queued before it asked.
    """

    def __init__(self, store: Store, interval_s: float = 0.5) -> None:
        self.store = store
        self.interval_s = interval_s
        self.flushed_frames = 0
        self.on_flush: Callable[[int], None] | None = None  # called with flushed_frames
        self._lock = threading.Lock()  # guards the queues
        self._flush_lock = threading.Lock()  # one flush at a time, in queue order
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._frames: list[FrameRows] = []
        self._events: list[EventRow] = []
        self._images: list[ImageRows] = []
        self._commands: list[dict[str, Any]] = []
        self._checkpoints: dict[str, tuple[float, bytes]] = {}
        store.commit_queued_with(self.flush)  # the store's reads see what is queued here

    def start(self) -> None:
        """Start the flushing thread (a no-op if it runs)."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="storage-writer", daemon=True)
        self._thread.start()

    def frames(
        self,
        rover: str,
        downlinks: Sequence[Mapping[str, Any]],
        truths: Sequence[Mapping[str, Any]],
        events: Sequence[tuple[float, Mapping[str, Any]]] = (),
        received_t_s: float | None = None,
    ) -> None:
        """Queue telemetry records, the downlink's and the truth's (the two lists of a
        ``server.sinks.FrameBatch``: paired, or either alone), with the events the downlink
        records carry, in one step: a flush never parts a frame from its events.
        ``received_t_s``: when the downlink reached the ground (across light time)."""
        with self._lock:
            self._frames.append((rover, list(downlinks), list(truths), received_t_s))
            self._events.extend((rover, float(t), e, received_t_s) for t, e in events)

    def events(
        self,
        rover: str,
        events: list[tuple[float, Mapping[str, Any]]],
        received_t_s: float | None = None,
    ) -> None:
        """Queue events as (t_s, ``{"text", "kind", "severity"}``) pairs."""
        with self._lock:
            self._events.extend((rover, float(t), e, received_t_s) for t, e in events)

    def images(
        self, rover: str, images: Sequence[ImageDict], received_t_s: float | None = None
    ) -> None:
        """Queue image products (``sim.loop.images``); a flush encodes each to PNG and
        stores it once (``server.storage.images``), off the clock thread."""
        with self._lock:
            self._images.append((rover, list(images), received_t_s))

    def command(self, rover: str, record: CommandRecord) -> None:
        """Queue one command execution."""
        row = command_row(rover, record)
        with self._lock:
            self._commands.append(row)

    def checkpoint(self, rover: str, t_s: float, blob: bytes) -> None:
        """Queue a rover's checkpoint; only the last one queued before a flush is written."""
        with self._lock:
            self._checkpoints[rover] = (t_s, blob)

    def flush(self) -> None:
        """Write everything queued so far; returns when it is committed (or dropped)."""
        with self._flush_lock:
            with self._lock:
                frames, self._frames = self._frames, []
                events, self._events = self._events, []
                images, self._images = self._images, []
                commands_, self._commands = self._commands, []
                saved, self._checkpoints = self._checkpoints, {}
            if not (frames or events or images or commands_ or saved):
                return
            store = self.store
            parts: list[tuple[str, Callable[[Connection], None]]] = [
                ("frames", lambda conn: store._insert_frames(conn, frames)),
                ("events", lambda conn: store._insert_events(conn, events)),
                ("images", lambda conn: insert_images(conn, images)),
                ("commands", lambda conn: store._record_commands(conn, commands_)),
                ("checkpoints", lambda conn: store._replace_checkpoints(conn, saved)),
            ]
            try:
                with store.engine.begin() as conn:
                    for _name, write in parts:
                        write(conn)
                written = sum(len(f[1]) for f in frames)
            except Exception:
                log.exception("storage batch failed; retrying each kind on its own")
                written = self._write_parts(parts, sum(len(f[1]) for f in frames))
            self.flushed_frames += written
            callback = self.on_flush
        if callback is not None:
            callback(self.flushed_frames)

    def _write_parts(
        self, parts: Iterable[tuple[str, Callable[[Connection], None]]], n_frames: int
    ) -> int:
        written = 0
        for name, write in parts:
            try:
                with self.store.engine.begin() as conn:
                    write(conn)
                if name == "frames":
                    written = n_frames
            except Exception:
                log.exception("storage: dropped a batch of %s", name)
        return written

    def stop(self) -> None:
        """Flush what is queued and end the thread."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        self.flush()

    def _run(self) -> None:
        # Deadlines from the start of each flush: a slow flush shortens the next wait
        # rather than stretching the interval.
        next_t = time.monotonic() + self.interval_s
        while not self._stop.wait(max(0.0, next_t - time.monotonic())):
            next_t = time.monotonic() + self.interval_s
            try:
                self.flush()
            except Exception:  # never let the thread die: the next interval retries
                log.exception("storage flush failed")
