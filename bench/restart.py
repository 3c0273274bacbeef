"""``roverops bench restart``: what a restart keeps (issue 13, defects 7 and 8).

Everything runs through the real server: ``roverops serve --no-3d`` in a subprocess on a
new SQLite database in a temporary directory (``bench.server.running_server``),
killed and restarted on the same database; the bench reads the database beside it (WAL: a
reader never blocks the server). The delays come from one seeded ``random.Random``.

- Kills: ``kills`` SIGKILLs while Spirit runs ``SEQUENCE`` (six steps, about 100
  simulated s) at speed ``KILL_SPEED``; every other kill at a random moment (up to
  ``KILL_WINDOW_S`` after the server answers), the others as soon as a step's row is
  stored, new or re-run (the moment a step could be stored twice). A sequence that
  completes is followed by another. ``restart_duplicate_step_rows``: rows beyond one per
  (sequence, step) at the end (rows are never deleted; target 0); ``restart_lost_steps``:
  steps of the sequences, all completed at the end, without a row with their own command
  (target 0); ``restart_rerun_steps``: re-runs the rows
  count (``reruns``), reported. ``restart_median_s``: from starting the process to its
  first answer of ``GET /api/rovers``, median over every restart of the bench.
- Pauses: Spirit mid-drive at ``KILL_SPEED`` is paused at a random moment, then killed at
  once (SIGKILL) or stopped (SIGTERM), alternately; ``restart_paused_kept_pct``: restarts
  that find it still paused (target 100).
- SIGTERM: ``restart_sigterm_rewind_s``, the most a stopped rover's clock went back: the
  ``t_s`` it had when stopped minus the ``t_s`` its checkpoint resumes at, read from the
  database once the process has ended. A paused rover (the SIGTERMs above) had the
  ``t_s`` the API showed once the pause took effect; a rover mid-drive at speed
  ``SIGTERM_SPEED``, the ``t_s`` of its last stored frame (target: at most one frame,
  ``FRAME_EVERY_S``).

Output contract: ``bench.result``.
"""

from __future__ import annotations

import contextlib
import math
import random
import signal
import statistics
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

from bench.result import bench_result
from bench.server_process import RunningServer, running_server, upload, wait_for
from sequences.validate import validate
from server.runtime import FRAME_EVERY_S, ROVERS, RoverRuntime
from server.storage import Store

ROVER = "spirit"
SEQUENCE = (
    "SEQUENCE restart_kills\n"
    "GET_TILT_ATTITUDE\n"
    "DRIVE_STRAIGHT distance_m=1\n"
    "WAIT duration_s=20\n"
    "TURN_IN_PLACE angle_deg=10\n"
    "NADIR_UPDATE\n"
    "DRIVE_STRAIGHT distance_m=1\n"
)
LONG_DRIVE = "SEQUENCE restart_long_drive\nDRIVE_STRAIGHT distance_m=100\n"
KILL_SPEED = 20.0  # x: the six steps take about 5 wall seconds
SIGTERM_SPEED = 100.0  # x: 5 simulated s a tick, what a periodic checkpoint lagged by
KILL_WINDOW_S = 2.0  # a random kill comes up to this long after the server answers
ROW_TIMEOUT_S = 30.0  # a targeted kill waits this long at most for a new row
DONE_TIMEOUT_S = 120.0
NO_3D = {"ROVEROPS_NO_3D": "1"}

TARGETS: dict[str, dict[str, float]] = {
    "restart_duplicate_step_rows": {"le": 0},
    "restart_lost_steps": {"le": 0},
    "restart_paused_kept_pct": {"ge": 100.0},
    "restart_sigterm_rewind_s": {"le": FRAME_EVERY_S},
}


@dataclass
class Restarts:
    """The server of one data directory through its restarts; ``restart_s`` the wall
    time of each start until it answered."""

    data_dir: Path
    server: RunningServer | None = None
    restart_s: list[float] = field(default_factory=list)
    _stack: contextlib.ExitStack = field(default_factory=contextlib.ExitStack)

    @property
    def url(self) -> str:
        return f"sqlite:///{self.data_dir / 'roverops.db'}"

    def start(self) -> RunningServer:
        started = time.perf_counter()
        self.server = self._stack.enter_context(running_server(self.data_dir, env=NO_3D))
        self.restart_s.append(time.perf_counter() - started)
        return self.server

    def end(self, sig: int) -> None:
        """Send ``sig`` and wait for the process to end."""
        assert self.server is not None
        self.server.process.send_signal(sig)
        self.server.process.wait(timeout=60.0)
        self._stack.close()
        self.server = None

    def close(self) -> None:
        self._stack.close()  # SIGTERM to a server still running


def _status(server: RunningServer, sequence_id: int) -> str:
    status: str = server.ok("GET", f"/api/sequences/{sequence_id}")["status"]
    return status


def _clock(server: RunningServer, body: dict[str, Any]) -> dict[str, Any]:
    clock: dict[str, Any] = server.ok("POST", f"/api/rovers/{ROVER}/clock", body)
    return clock


def _rows(store: Store) -> list[dict[str, Any]]:
    return store.commands(ROVER, -1e300, 1e300)


# ---- kills during a sequence ------------------------------------------------------------


@dataclass
class KillRun:
    """What ``measure_kills`` saw: after each restart, the rows per (sequence, step); at
    the end, each sequence's status and its rows as (step, command, reruns), in step order."""

    kills: int = 0
    targeted: int = 0
    sequences: list[int] = field(default_factory=list)
    rows_after_restart: list[dict[tuple[int, int], int]] = field(default_factory=list)
    statuses: dict[int, str] = field(default_factory=dict)
    final_rows: dict[int, list[tuple[int, str, int]]] = field(default_factory=dict)
    restart_s: list[float] = field(default_factory=list)


def measure_kills(data_dir: Path, kills: int, rng: random.Random) -> KillRun:
    """``kills`` SIGKILLs while ``SEQUENCE`` runs (module docstring), then every sequence
    uploaded run to its end."""
    run = KillRun()
    restarts = Restarts(data_dir)
    try:
        server = restarts.start()
        _clock(server, {"speed": KILL_SPEED})
        store = Store(restarts.url)
        try:
            for k in range(kills):
                if not run.sequences or _status(server, run.sequences[-1]) == "completed":
                    run.sequences.append(upload(server, ROVER, SEQUENCE))
                if k % 2:  # right after a step's row is stored (new, or updated by a re-run)
                    run.targeted += _until_a_row(store, server, run.sequences[-1])
                else:
                    time.sleep(rng.uniform(0.0, KILL_WINDOW_S))
                restarts.end(signal.SIGKILL)
                run.kills += 1
                server = restarts.start()
                run.rows_after_restart.append(_counts(_rows(store)))
            for sequence_id in run.sequences:
                with contextlib.suppress(RuntimeError):  # counted as lost below
                    wait_for(partial(_ended, server, sequence_id), DONE_TIMEOUT_S, "the end")
                run.statuses[sequence_id] = _status(server, sequence_id)
            rows = _rows(store)  # a sequence's rows are stored before it reads completed
        finally:
            store.close()
    finally:
        restarts.close()
    for row in sorted(rows, key=lambda r: (r["sequence_id"], r["step_index"], r["id"])):
        step = (int(row["step_index"]), str(row["command"]), int(row["reruns"]))
        run.final_rows.setdefault(int(row["sequence_id"]), []).append(step)
    run.restart_s = restarts.restart_s
    return run


def _recorded(store: Store) -> int:
    """How many times steps were recorded: rows and their re-runs."""
    return sum(1 + int(r["reruns"]) for r in _rows(store))


def _until_a_row(store: Store, server: RunningServer, sequence_id: int) -> bool:
    """Wait until a step is recorded (True), or the sequence ends without one (False)."""
    stored = _recorded(store)

    def recorded_or_ended() -> int:
        return 1 if _recorded(store) > stored else 2 if _ended(server, sequence_id) else 0

    with contextlib.suppress(RuntimeError):
        return bool(wait_for(recorded_or_ended, ROW_TIMEOUT_S, "a row") == 1)
    return False


def _ended(server: RunningServer, sequence_id: int) -> bool:
    return _status(server, sequence_id) in ("completed", "failed", "cancelled")


def _counts(rows: list[dict[str, Any]]) -> dict[tuple[int, int], int]:
    return dict(Counter((int(r["sequence_id"]), int(r["step_index"])) for r in rows))


def expected_steps() -> list[str]:
    """The command of each step of ``SEQUENCE``, as its rows hold it."""
    parsed = validate(SEQUENCE).sequence
    assert parsed is not None
    return [s.command.describe() for s in parsed.steps]


def kill_metrics(run: KillRun) -> dict[str, Any]:
    """The figures of a ``KillRun`` (module docstring)."""
    expected = list(enumerate(expected_steps()))
    final = Counter((s, i) for s, rows in run.final_rows.items() for i, _c, _r in rows)
    duplicates = sum(n - 1 for n in final.values())  # rows are never deleted
    lost = 0
    for sequence_id in run.sequences:
        got = {(i, c) for i, c, _r in run.final_rows.get(sequence_id, [])}
        if run.statuses.get(sequence_id) != "completed":
            lost += len(expected)
        else:
            lost += sum(1 for step in expected if step not in got)
    return {
        "restart_kills": run.kills,
        "restart_kills_after_a_row": run.targeted,
        "restart_sequences": len(run.sequences),
        "restart_steps": len(run.sequences) * len(expected),
        "restart_duplicate_step_rows": duplicates,
        "restart_lost_steps": lost,
        "restart_rerun_steps": sum(r for rows in run.final_rows.values() for _i, _c, r in rows),
    }


# ---- pauses and graceful stops ------------------------------------------------------------


def _settled_t_s(server: RunningServer) -> float:
    """The paused rover's ``t_s`` once the pause took effect (two reads 0.3 s apart)."""

    def settled() -> float | None:
        first = float(server.ok("GET", f"/api/rovers/{ROVER}/state")["t_s"])
        time.sleep(0.3)
        second = float(server.ok("GET", f"/api/rovers/{ROVER}/state")["t_s"])
        return first if first == second else None

    t_s: float = wait_for(settled, 30.0, "the pause to take effect")
    return t_s


def measure_pauses(data_dir: Path, trials: int, rng: random.Random) -> dict[str, Any]:
    """Pause mid-drive, then SIGKILL at once or SIGTERM, alternately; restart."""
    restarts = Restarts(data_dir)
    kept: list[bool] = []
    rewinds: list[float] = []
    try:
        server = restarts.start()
        _clock(server, {"speed": KILL_SPEED})
        upload(server, ROVER, LONG_DRIVE)
        for k in range(trials):
            time.sleep(rng.uniform(0.2, KILL_WINDOW_S))
            _clock(server, {"action": "pause"})
            sig = signal.SIGTERM if k % 2 else signal.SIGKILL
            paused_t_s = _settled_t_s(server) if sig == signal.SIGTERM else None
            restarts.end(sig)
            if paused_t_s is not None:
                rewinds.append(paused_t_s - _resumes_at(restarts.url)[1])
            server = restarts.start()
            state = server.ok("GET", f"/api/rovers/{ROVER}/state")
            kept.append(state["clock"]["running"] is False)
            _clock(server, {"action": "resume"})
    finally:
        restarts.close()
    return {
        "kept": kept,
        "rewinds_s": rewinds,
        "restart_s": restarts.restart_s,
    }


def _driving(server: RunningServer) -> bool:
    state = server.ok("GET", f"/api/rovers/{ROVER}/state")
    return bool(state["frame"]) and str(state["executing"]).startswith("DRIVE_STRAIGHT")


def _resumes_at(url: str) -> tuple[float, float]:
    """Of a stopped server's database: the last stored frame's ``t_s`` (``-inf`` if none)
    and the ``t_s`` the rover's checkpoint resumes at."""
    store = Store(url)
    try:
        last, saved = store.last_frame(ROVER), store.load_checkpoint(ROVER)
    finally:
        store.close()
    if saved is None:
        raise RuntimeError("no checkpoint stored")
    last_t_s = -math.inf if last is None else float(last["t_s"])
    return last_t_s, RoverRuntime.restore(ROVERS[ROVER], saved[1]).t_s


def measure_sigterm(data_dir: Path, trials: int, rng: random.Random) -> dict[str, Any]:
    """SIGTERM mid-drive at ``SIGTERM_SPEED``: how far before the last stored frame the
    checkpoint resumes; restart and go on."""
    restarts = Restarts(data_dir)
    rewinds: list[float] = []
    try:
        server = restarts.start()
        _clock(server, {"speed": SIGTERM_SPEED})
        upload(server, ROVER, LONG_DRIVE)
        for _ in range(trials):
            wait_for(partial(_driving, server), 60.0, "the drive's frames")
            time.sleep(rng.uniform(0.0, KILL_WINDOW_S))
            restarts.end(signal.SIGTERM)
            last_t_s, resumed_t_s = _resumes_at(restarts.url)
            rewinds.append(last_t_s - resumed_t_s)
            server = restarts.start()
    finally:
        restarts.close()
    return {"rewinds_s": rewinds, "restart_s": restarts.restart_s}


# ---- the bench ------------------------------------------------------------------------------


def bench_restart(
    kills: int = 20, pauses: int = 10, sigterms: int = 4, seed: int = 13
) -> dict[str, Any]:
    """The restart bench (module docstring); smaller counts make a quick run."""
    rng = random.Random(seed)
    with tempfile.TemporaryDirectory(prefix="roverops-bench-restart-") as tmp:
        root = Path(tmp)
        for name in ("kills", "pauses", "sigterm"):
            (root / name).mkdir()
        run = measure_kills(root / "kills", kills, rng)
        paused = measure_pauses(root / "pauses", pauses, rng)
        stopped = measure_sigterm(root / "sigterm", sigterms, rng)
    metrics = kill_metrics(run)
    kept = paused["kept"]
    rewinds = [*paused["rewinds_s"], *stopped["rewinds_s"]]
    restart_s = [*run.restart_s[1:], *paused["restart_s"][1:], *stopped["restart_s"][1:]]
    metrics.update(
        {
            "restart_paused_trials": len(kept),
            "restart_paused_kept_pct": 100.0 * sum(kept) / len(kept) if kept else math.nan,
            "restart_sigterm_trials": len(rewinds),
            "restart_sigterm_rewind_s": max(0.0, *rewinds) if rewinds else math.nan,
            "restart_median_s": statistics.median(restart_s) if restart_s else math.nan,
            "restart_restarts": len(restart_s),
        }
    )
    return bench_result("restart", metrics, TARGETS)
