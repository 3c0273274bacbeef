"""A rover's queue as the console shows it: each queued sequence in order with every step's
status, and the sequences that left it last; and the ``queue`` notices that let consoles
follow it without polling.

A queued sequence's steps come from the runtime (``RoverRuntime.queue_snapshot``): the
steps done carry their outcome (the command report's status, reason and times), the step
executing or playing out is ``running``, the rest ``pending`` (``skipped`` after a refused
step stopped the sequence). The runtime is the source, not the commands table, because a
notice is due the moment a step changes, and the storage writer commits its rows up to
half a second later. Sequences that left the queue come from storage: their steps'
command rows, and ``skipped`` for the steps that never ran (cancelled, or after a refusal).

Notices are snapshots (``{"type": "queue", "rover", "queue"}``), so one built after several
changes says all of them: ``QueueNotices`` builds them off the clock thread (which only
marks its rover changed), at most one per ``MIN_INTERVAL_S`` per rover, and only for a rover
someone follows.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

from sqlalchemy import select

from sequences.language import SequenceStep
from server.notices import QueueNotice
from server.queue import tag_text
from server.runtime import QueueEntry, RoverRuntime
from server.storage import Store, commands
from sim.world.marsclock import t_s_to_utc

log = logging.getLogger(__name__)

RECENT = 5  # sequences that left the queue, listed after it
FINAL = ("completed", "failed", "cancelled")
MIN_INTERVAL_S = 0.1  # between two notices of a rover (wall time)


def _when(runtime: RoverRuntime, t_s: float | None) -> dict[str, Any] | None:
    if t_s is None:
        return None
    return {"t_s": t_s, "utc": t_s_to_utc(t_s).isoformat(), "lmst_h": runtime.lmst_h(t_s),
            "sol": runtime.sol(t_s)}  # fmt: skip


def _step(
    runtime: RoverRuntime, entry: QueueEntry, index: int, step: SequenceStep
) -> dict[str, Any]:
    out: dict[str, Any] = {
        "index": index,
        "line": step.line,
        "command": step.command.describe(),
        "tag": tag_text(step.time_tag),
        "status": "pending",
        "reason": None,
        "start": None,
        "end": None,
    }
    if index == entry.running_step:
        out["status"] = "running"
    if index < len(entry.outcomes):
        done = entry.outcomes[index]
        out["start"] = _when(runtime, done.start_t_s)
        out["end"] = _when(runtime, done.end_t_s)
        out["reason"] = done.reason
        if out["status"] != "running":  # its frames still play out: it runs until then
            out["status"] = done.status
    elif entry.stopped:
        out["status"] = "skipped"
    elif index < entry.next_step:  # done before a restart from an older version's checkpoint
        out["status"] = "completed"
    return out


def queue_json(runtime: RoverRuntime, store: Store | None = None) -> list[dict[str, Any]]:
    """The rover's queue in order (``position`` 0 runs next), every step with its status;
    ``movable`` false with ``pinned`` saying why for a sequence that keeps its place;
    ``submitted_by`` when ``store`` is given."""
    if runtime.comm.mission is not None and store is not None:  # across light time
        from server.comm.queue_sides import mission_queue_json

        return mission_queue_json(runtime, store)
    entries = runtime.queue_snapshot()
    who = store.submitters(e.sequence_id for e in entries) if store is not None else {}
    return [
        {
            "position": position,
            "sequence_id": e.sequence_id,
            "name": e.sequence.name,
            "immediate": e.immediate,
            "status": "running" if e.started else "queued",
            "movable": e.pinned is None,
            "pinned": e.pinned,
            "submitted_by": who.get(e.sequence_id),
            "next_step": e.next_step,
            "step_count": len(e.sequence.steps),
            "steps": [_step(runtime, e, i, s) for i, s in enumerate(e.sequence.steps)],
        }
        for position, e in enumerate(entries)
    ]


def _stored_command(step: dict[str, Any]) -> str:
    """``NAME arg=value ...`` of a stored step (``server.api.sequences.step_json``)."""
    args = " ".join(
        f"{k}={str(v).lower() if isinstance(v, bool) else v}"
        for k, v in (step.get("args") or {}).items()
        if v is not None
    )
    return f"{step.get('command', '?')} {args}".strip()


def recent_json(runtime: RoverRuntime, store: Store, limit: int = RECENT) -> list[dict[str, Any]]:
    """The rover's last ``limit`` sequences that left the queue (completed, failed or
    cancelled), newest first, each step with its command row's status and times, or
    ``skipped`` where it never ran. Call after the storage writer flushed."""
    rover = runtime.spec.name
    found = [s for s in store.list_sequences(rover) if s["status"] in FINAL][:limit]
    ids = [s["id"] for s in found]
    rows: dict[tuple[int, int], dict[str, Any]] = {}
    if ids:
        query = select(commands).where(commands.c.sequence_id.in_(ids))
        with store.engine.connect() as conn:
            for r in conn.execute(query):
                rows[(int(r.sequence_id), int(r.step_index))] = dict(r._mapping)
    out = []
    for summary in found:
        stored = store.get_sequence(summary["id"]) or {}
        steps = []
        for index, step in enumerate(stored.get("steps") or []):
            row = rows.get((summary["id"], index))
            steps.append(
                {
                    "index": index,
                    "line": step.get("line"),
                    "command": row["command"] if row else _stored_command(step),
                    "tag": "",
                    "status": row["status"] if row else "skipped",
                    "reason": row["reason"] if row else None,
                    "start": _when(runtime, row["start_t_s"]) if row else None,
                    "end": _when(runtime, row["end_t_s"]) if row else None,
                }
            )
        out.append(
            {
                "sequence_id": summary["id"],
                "name": summary["name"],
                "status": summary["status"],
                "detail": summary["detail"],
                "submitted_by": summary.get("submitted_by"),
                "step_count": len(steps),
                "steps": steps,
                "stages": [
                    {**g, "when": _when(runtime, g["t_s"])} for g in stored.get("stages") or []
                ],
            }
        )
    return out


class QueueNotices:
    """Queue notices, built and sent by a thread of their own (module docstring).
    ``changed(rover)`` is what the runtimes' listener calls (``Server.queue_changed``): it
    never waits.
    ``build(rover)`` makes a notice, ``send(rover, notice)`` hands it on (the hub), and
    ``wanted(rover)`` says whether anyone follows the rover."""

    def __init__(
        self,
        build: Callable[[str], QueueNotice],
        send: Callable[[str, QueueNotice], None],
        wanted: Callable[[str], bool],
        min_interval_s: float = MIN_INTERVAL_S,
    ) -> None:
        self.build, self.send, self.wanted = build, send, wanted
        self.min_interval_s = min_interval_s
        self._dirty: set[str] = set()
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def changed(self, rover: str) -> None:
        """Mark ``rover``'s queue changed (a notice follows within ``min_interval_s``)."""
        with self._lock:
            self._dirty.add(rover)
        self._wake.set()

    def start(self) -> None:
        """Start the sending thread."""
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="queue-notices", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """End the sending thread."""
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=10.0)
            self._thread = None

    def send_pending(self) -> None:
        """Build and send a notice for each rover marked changed (and followed)."""
        with self._lock:
            rovers, self._dirty = self._dirty, set()
        for rover in sorted(rovers):
            if not self.wanted(rover):
                continue
            try:
                self.send(rover, self.build(rover))
            except Exception:  # never let the thread die: the next change sends again
                log.exception("queue notice for %s failed", rover)

    def _run(self) -> None:
        while not self._stop.is_set():
            self._wake.wait()
            self._wake.clear()
            if self._stop.is_set():
                return
            self.send_pending()
            self._stop.wait(self.min_interval_s)  # changes meanwhile go in the next one
