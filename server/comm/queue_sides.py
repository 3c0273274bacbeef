"""The queue across light time, as the ground knows it: both sides of the link.

On the ground (``side`` ``ground``): the sequences accepted and waiting for their uplink
window (``waiting``), in the order they will be radiated, each with when its window will
radiate it; then those radiated and on their way up (``radiated``), with when they reach
the rover. Onboard (``side`` ``onboard``): the sequences the ground radiated and has not yet
heard end, each step as its command report says (``pending`` where none has come down: the
ground does not know). It never reads the rover's own queue: that is what the rover knows.
"""

from __future__ import annotations

from typing import Any

from sqlalchemy import select

from server.comm.view import when
from server.queue import QueuedSequence, tag_text
from server.runtime import RoverRuntime
from server.storage import Store, commands


def _steps_of(entry: QueuedSequence, runtime: RoverRuntime) -> list[dict[str, Any]]:
    return [{"index": i, "line": s.line, "command": s.command.describe(),
             "tag": tag_text(s.time_tag), "status": "pending", "reason": None, "start": None,
             "end": None} for i, s in enumerate(entry.sequence.steps)]  # fmt: skip


def _entry(
    runtime: RoverRuntime, store: Store, sequence_id: int, side: str, status: str,
    steps: list[dict[str, Any]], immediate: bool, who: dict[int, str | None],
) -> dict[str, Any]:  # fmt: skip
    stored = store.get_sequence(sequence_id) or {}
    stages = [{**s, "when": when(runtime, s["t_s"])} for s in stored.get("stages") or []]
    done = sum(1 for s in steps if s["status"] not in ("pending", "running"))
    return {
        "sequence_id": sequence_id, "name": stored.get("name"), "immediate": immediate,
        "status": status, "movable": False,
        "pinned": "is across the light time: the rover's queue is not reordered from the ground"
        if side == "onboard" else "waits for its uplink window in the order accepted",
        "submitted_by": who.get(sequence_id), "next_step": done, "step_count": len(steps),
        "steps": steps, "side": side, "stages": stages,
    }  # fmt: skip


def mission_queue_json(runtime: RoverRuntime, store: Store) -> list[dict[str, Any]]:
    """Both sides of the link (module docstring), ground first, then onboard."""
    mission = runtime.comm.mission
    assert mission is not None
    with runtime.lock:
        ground = mission.ground_view()
        waiting = list(mission.link.waiting)
        rising = list(mission.link.rising)
    out: list[dict[str, Any]] = []
    ids = [u.sequence_id for u in (*waiting, *rising) if u.kind == "sequence"]
    onboard = [i for i in ground["radiated_ids"] if i not in ids]
    who = store.submitters([*ids, *onboard])
    for uplink in (*waiting, *rising):
        if uplink.kind != "sequence":
            continue
        entry = QueuedSequence.from_state(uplink.payload)
        status = "waiting" if uplink.radiated_t_s is None else "radiated"
        item = _entry(runtime, store, uplink.sequence_id, "ground", status,
                      _steps_of(entry, runtime), entry.immediate, who)  # fmt: skip
        if uplink.radiated_t_s is None:
            found = mission.link.radiation(uplink, max(uplink.accepted_t_s, mission.link.up_t_s))
            item["radiate"] = None if found is None else when(runtime, found[1])
        else:
            item["arrive"] = when(runtime, uplink.arrival_t_s)
        out.append(item)
    rows: dict[tuple[int, int], Any] = {}
    if onboard:
        query = select(commands).where(commands.c.sequence_id.in_(onboard))
        with store.engine.connect() as conn:
            rows = {(int(r.sequence_id), int(r.step_index)): r for r in conn.execute(query)}
    for sequence_id in onboard:
        stored = store.get_sequence(sequence_id) or {}
        steps = []
        for index, step in enumerate(stored.get("steps") or []):
            row = rows.get((sequence_id, index))
            steps.append({"index": index, "line": step.get("line"),
                          "command": row.command if row else str(step.get("command", "?")),
                          "tag": "", "status": row.status if row else "pending",
                          "reason": row.reason if row else None,
                          "start": when(runtime, row.start_t_s) if row else None,
                          "end": when(runtime, row.end_t_s) if row else None})  # fmt: skip
        status = "running" if stored.get("status") == "running" else "queued"
        out.append(_entry(runtime, store, sequence_id, "onboard", status, steps,
                          stored.get("format") == "command", who))  # fmt: skip
    for position, item in enumerate(out):
        item["position"] = position
    return out
