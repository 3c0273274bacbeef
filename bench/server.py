"""``roverops bench server``: the operations server's speed figures (issue 4, item 7).

Everything runs through the real server: ``roverops serve`` in a subprocess on a free port
of 127.0.0.1, a new SQLite database in a temporary directory, its storage writer, its rover
threads and uvicorn's real sockets. The bench process is the client (REST over
``urllib``, WebSocket with the ``websockets`` package), so clients and server do not share
an interpreter lock and the figures include the network stack.

- ``sol_sim_wall_s``: a sol's work (GET_FINE_ATTITUDE, a 100 m DRIVE_STRAIGHT, a 15 min
  HGA_PASS) on Spirit at speed ``max``: wall time from the upload request to the sequence
  reading ``completed`` through the API, read when the rover's WebSocket (one client, as a
  console) brings the event of its end, which the server sends once the status is stored
  (its frames, commands and events committed before: the runtime flushes the writer
  first). Polling the status every ``POLL_S`` instead slowed the simulation in the server
  by ~0.7 s (its requests taking turns for the interpreter lock). The same text
  is validated against Spirit first, untimed: the server's validation worker warms up in
  the background after a start (``server.validation.pool``), and the sol is not to wait
  for that (half a second on 2 cores).
- ``sol_in_process_wall_s``: the same commands in a ``RoverSession`` of this process, as
  the server makes Spirit's (its site, seed, start and ``frame_every_s``): the simulation
  alone, measured just before the server starts; ``sol_server_overhead_s`` is
  ``sol_sim_wall_s`` minus it, what the server adds (play-out, frames as dicts, storage,
  alarms, the 3D view, checkpoints, HTTP and polling). The sol's figures are medians of
  ``sol_repeats`` pairs (a new server for each), the rest is measured on the last server.
- ``ws_clients``, ``ws_p99_latency_ms``, ``ws_msgs_per_client_per_s``: Spirit articulating
  (NATE at 8 Hz, one frame kept per simulated second) at speed 8, so it should publish 8
  frames per wall second (``ws_rover_speed_seen_x``: the speed its frames show). The WAIT
  is only as long as the measurement needs: the runtime computes a command whole before
  playing it out. ``ws_clients`` WebSocket clients (permessage-deflate, as a browser)
  collect for ``ws_window_s``; a message's latency is its receive wall time minus the
  ``published_wall`` stamp the hub put on it (``server.hub``); the p99 is over every
  message of every client in the window. ``ws_clients`` counts the clients held all
  through the window (never a second without a message).
- ``validate_10k_lines_s``: ``sequences.validate.validate`` of a 10,000-line sequence
  made of the example files' commands (median of ``repeats``), without a rover context as
  ``roverops validate`` runs it; ``validate_10k_lines_with_rover_s`` the same with Spirit's
  ``ValidationContext`` (the upload route's warnings walk), reported without a target.
- ``validate_100k_blank_lines_s``: wall time of ``POST /api/sequences/validate`` (through
  the server) of 100,000 blank lines then one command (issue 13, defect 4);
  ``upload_100k_blank_lines_s`` the same text uploaded to a paused rover (the upload also
  finds the sequence's declared name), reported without a target.
- ``event_loop_stall_ms_during_upload``: p99 latency of ``GET /api/rovers`` polled every
  ``STALL_POLL_S`` from another thread while a 1 MB sequence (the examples' commands, as
  ``validate_10k_lines_s``) is validated against Spirit (``/validate?rover=spirit``, the
  heaviest validation a client can ask for); ``upload_1mb_validate_s`` how long that took
  and ``event_loop_stall_samples`` how many polls it covered; ``event_loop_idle_p99_ms``
  the p99 of ``STALL_IDLE_POLLS`` polls just before, with nothing validating (on a shared
  machine, the part of the stall that is not the server's).
- ``channel_query_7_sols_s``: ``GET /api/rovers/spirit/channels/tilt_est_deg`` over 7 sols
  stored (``FIRST_SOL`` on, before Spirit's start, so its own frames do not mix in) on a
  server of its own without its 3D view (whose start reads the whole stored history), the
  median of ``repeats``; ``channel_query_7_sols_truth_s`` the same of a truth channel, without
  a target. The sols are stored straight through ``Store`` and its ``BatchWriter`` before the
  server starts: the real records of a session made as Spirit's (``TEMPLATE_SEQUENCE``),
  repeated one every ``every_s`` (default ``FRAME_EVERY_S``: every simulated second of 7
  sols, the most the server keeps, about 621,000 frames), each copy's ``t_s``, ``sol`` and
  ``lmst_h`` anew on Spirit's clock, its events dropped (``channel_rows_stored``,
  ``channel_store_wall_s``).

Output contract: ``bench.result``. The server runs as ``bench.server_process`` starts it.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import re
import statistics
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.result import bench_result
from bench.server_process import POLL_S, RunningServer, running_server, upload, wait_for
from sequences.validate import validate

EXAMPLES = Path(__file__).resolve().parent.parent / "sequences" / "examples"
ROVER = "spirit"
WS_SPEED = 8.0  # x: with one frame per simulated second, 8 frames per wall second
WS_WARMUP_S = 20.0  # simulated WAIT beyond the window, in wall seconds at WS_SPEED

SOL_SEQUENCE = (
    "SEQUENCE bench_sol\n"
    "GET_FINE_ATTITUDE\n"
    "DRIVE_STRAIGHT distance_m={drive_m:g}\n"
    "HGA_PASS duration_min={hga_min:g}\n"
)
WS_SEQUENCE = "SEQUENCE bench_ws\nARTICULATE_START\nWAIT duration_s={wait_s:g}\nARTICULATE_STOP\n"

TARGETS: dict[str, dict[str, float]] = {
    "sol_sim_wall_s": {"le": 5.0},  # issue 16
    "ws_clients": {"ge": 50},
    "ws_p99_latency_ms": {"le": 100.0},
    "validate_10k_lines_s": {"le": 0.5},
    "validate_100k_blank_lines_s": {"le": 1.0},
    "event_loop_stall_ms_during_upload": {"le": 100.0},
    "channel_query_7_sols_s": {"le": 0.5},  # issue 21
}
BLANK_LINES = 100_000
UPLOAD_BYTES = 990_000  # under the server's 1,000,000-byte limit
STALL_POLL_S = 0.01
STALL_IDLE_POLLS = 200


# ---- the sol --------------------------------------------------------------------------------


def measure_sol(
    server: RunningServer, drive_m: float = 100.0, hga_min: float = 15.0, timeout_s: float = 300.0
) -> dict[str, Any]:
    """The sol's sequence at speed ``max``: wall time from upload to ``completed``, and
    what the rover did (simulated span, distance, commands not completed)."""
    from websockets.sync.client import connect as ws_connect

    text = SOL_SEQUENCE.format(drive_m=drive_m, hga_min=hga_min)
    server.ok("POST", f"/api/sequences/validate?rover={ROVER}", text)  # the worker warm
    server.ok("POST", f"/api/rovers/{ROVER}/clock", {"speed": "max"})
    before = server.ok("GET", f"/api/rovers/{ROVER}/state")
    with ws_connect(server.ws_url(ROVER), proxy=None, open_timeout=30.0) as ws:
        start = time.perf_counter()
        sequence_id = upload(server, ROVER, text)
        status = _sequence_end(server, ws, sequence_id, timeout_s)
        wall_s = time.perf_counter() - start
    if status != "completed":
        raise RuntimeError(f"the sol's sequence ended {status}:\n{server.log_tail()}")
    state = wait_for(
        lambda: (s := server.ok("GET", f"/api/rovers/{ROVER}/state"))["executing"] == "" and s,
        30.0,
        "the play-out",
    )
    frame = state["frame"] or {}
    p_s = frame.get("p_s_est") or [math.nan, math.nan]
    commands = failed = 0
    for sol in server.ok("GET", f"/api/rovers/{ROVER}/sols"):
        summary = server.ok("GET", f"/api/rovers/{ROVER}/sols/{sol}/timeline")["summary"]
        commands += summary["commands"]
        failed += summary["commands_failed"]
    return {
        "sol_sim_wall_s": wall_s,
        "sol_sim_simulated_s": float(state["t_s"]) - float(before["t_s"]),
        "sol_sim_distance_m": math.hypot(float(p_s[0]), float(p_s[1])),
        "sol_sim_commands": commands,
        "sol_sim_commands_not_completed": failed,
    }


def _sequence_end(server: RunningServer, ws: Any, sequence_id: int, timeout_s: float) -> str:
    """How the sequence ended, read through the API once the WebSocket's ``event`` notice of
    its end arrives (the server sends it after storing the status; a notice of its start,
    or of another sequence, is passed over, as are frames)."""
    deadline = time.monotonic() + timeout_s
    while (left := deadline - time.monotonic()) > 0.0:
        try:
            message = json.loads(ws.recv(timeout=left))
        except TimeoutError:
            break
        event = message.get("event") or {}
        if message.get("type") != "event" or event.get("kind") != "sequence":
            continue
        if not str(event.get("text", "")).startswith(f"sequence #{sequence_id} "):
            continue
        status: str = server.ok("GET", f"/api/sequences/{sequence_id}")["status"]
        if status in ("completed", "failed", "cancelled"):
            return status
    raise RuntimeError(f"timed out after {timeout_s:g} s waiting for the sol's sequence")


def spirit_session(text: str) -> tuple[Any, list[Any]]:
    """A ``RoverSession`` made as the server makes Spirit's (its site, seed, start and
    ``frame_every_s``), and the commands of sequence ``text``."""
    from server.runtime import FRAME_EVERY_S, ROVERS
    from sim.loop.session import RoverSession

    result = validate(text)
    assert result.sequence is not None, result.errors
    spec = ROVERS[ROVER]
    session = RoverSession(
        spec.site, spec.seed, spec.start_utc, frame_every_s=FRAME_EVERY_S, estimators=("sapp",)
    )
    return session, [step.command for step in result.sequence.steps]


def measure_sol_in_process(drive_m: float = 100.0, hga_min: float = 15.0) -> dict[str, Any]:
    """The sol's commands in Spirit's session (``spirit_session``): the wall time of their
    execution (module docstring)."""
    session, commands = spirit_session(SOL_SEQUENCE.format(drive_m=drive_m, hga_min=hga_min))
    start = time.perf_counter()
    for command in commands:
        session.execute(command, label=command.describe())
    return {"sol_in_process_wall_s": time.perf_counter() - start}


def _paired(reference: dict[str, Any], sol: dict[str, Any]) -> dict[str, Any]:
    """A sol through the server with its in-process reference, and the difference."""
    overhead = sol["sol_sim_wall_s"] - reference["sol_in_process_wall_s"]
    return {**reference, **sol, "sol_server_overhead_s": overhead}


def _median(values: list[Any]) -> Any:
    """The median; of counts, one of them (not the mean of the middle two)."""
    if all(isinstance(v, int) for v in values):
        return statistics.median_low(values)
    return statistics.median(values)


# ---- live telemetry ------------------------------------------------------------------------


@dataclass
class Received:
    """What one WebSocket client received: per message its receive wall time, latency,
    frame time and command; the last ``dropped`` it was told."""

    wall: list[float] = field(default_factory=list)
    latency_s: list[float] = field(default_factory=list)
    t_s: list[float] = field(default_factory=list)
    commands: list[str] = field(default_factory=list)
    dropped: int = 0

    def add(self, message: str | bytes) -> dict[str, Any]:
        """Record one frame (a notice is returned, not recorded); the message."""
        now = time.time()
        frame: dict[str, Any] = json.loads(message)
        if "type" in frame:  # a notice (server.hub: an alarm, ...), not a frame
            return frame
        self.wall.append(now)
        self.latency_s.append(now - float(frame["published_wall"]))
        self.t_s.append(float(frame["t_s"]))
        self.commands.append(str(frame.get("command", "")))
        self.dropped = int(frame.get("dropped", 0))
        return frame

    def between(self, lo: float, hi: float) -> list[int]:
        """Indices of the messages received from ``lo`` to ``hi`` (wall clock)."""
        return [i for i, w in enumerate(self.wall) if lo <= w <= hi]

    def sim_speed_x(self, lo: float, hi: float) -> float:
        """Simulated seconds per wall second of the frames received from ``lo`` to ``hi``."""
        idx = self.between(lo, hi)
        if len(idx) < 2:
            return math.nan
        first, last = idx[0], idx[-1]
        return (self.t_s[last] - self.t_s[first]) / (self.wall[last] - self.wall[first])


async def listen(ws: Any, into: Received) -> None:
    """Record every message of ``ws`` until it closes (or the task is cancelled)."""
    async for message in ws:
        into.add(message)


async def _fan_out(url: str, n_clients: int, window_s: float) -> tuple[list[Received], float]:
    from websockets.asyncio.client import connect

    received = [Received() for _ in range(n_clients)]
    async with contextlib.AsyncExitStack() as stack:
        sockets = []
        for _ in range(n_clients):
            ws = await stack.enter_async_context(connect(url, proxy=None, open_timeout=30.0))
            sockets.append(ws)
        tasks = [
            asyncio.create_task(listen(ws, r)) for ws, r in zip(sockets, received, strict=True)
        ]
        # the window opens once every client receives the WAIT's frames (the play-out runs)
        deadline = time.monotonic() + 60.0
        while not all(r.commands and r.commands[-1].startswith("WAIT") for r in received):
            if time.monotonic() > deadline or any(t.done() for t in tasks):
                raise RuntimeError("the clients did not receive the WAIT's frames")
            await asyncio.sleep(POLL_S)
        await asyncio.sleep(1.0)
        opened = time.time()
        await asyncio.sleep(window_s)
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
    return received, opened


def measure_ws(
    server: RunningServer, n_clients: int = 50, window_s: float = 10.0
) -> dict[str, Any]:
    """``n_clients`` WebSocket clients on Spirit articulating at speed 8 for ``window_s``."""
    server.ok("POST", f"/api/rovers/{ROVER}/clock", {"speed": WS_SPEED})
    wait_s = math.ceil(WS_SPEED * (window_s + WS_WARMUP_S + n_clients * 0.05))
    upload(server, ROVER, WS_SEQUENCE.format(wait_s=wait_s))
    received, opened = asyncio.run(_fan_out(server.ws_url(ROVER), n_clients, window_s))
    closed = opened + window_s
    latencies: list[float] = []
    rates: list[float] = []
    speeds: list[float] = []
    held = 0
    for r in received:
        idx = r.between(opened, closed)
        latencies += [r.latency_s[i] for i in idx]
        rates.append(len(idx) / window_s)
        speeds.append(r.sim_speed_x(opened, closed))
        # held: messages all through the window, never a second without one
        walls = [opened, *(r.wall[i] for i in idx), closed]
        held += bool(len(idx) > 0 and np.max(np.diff(walls)) < 1.0)
    lat_ms = np.asarray(latencies) * 1000.0
    have = lat_ms.size > 0
    return {
        "ws_clients": held,
        "ws_clients_connected": n_clients,
        "ws_p99_latency_ms": float(np.percentile(lat_ms, 99)) if have else math.nan,
        "ws_p50_latency_ms": float(np.percentile(lat_ms, 50)) if have else math.nan,
        "ws_max_latency_ms": float(lat_ms.max()) if have else math.nan,
        "ws_msgs_per_client_per_s": statistics.median(rates),
        "ws_messages": int(lat_ms.size),
        "ws_dropped_frames": sum(r.dropped for r in received),
        "ws_window_s": window_s,
        "ws_rover_speed_set_x": WS_SPEED,
        # the clock as the frames show it (simulated s per wall s over the window)
        "ws_rover_speed_seen_x": statistics.median(speeds),
    }


# ---- validation ---------------------------------------------------------------------------


def example_blocks() -> list[list[str]]:
    """The command lines of each text example sequence, comments and headers stripped."""
    blocks = []
    for path in sorted(EXAMPLES.glob("*.seq")):
        lines = []
        for raw in path.read_text(encoding="utf-8").splitlines():
            line = raw.split("#", 1)[0].strip()
            if line and not line.upper().startswith("SEQUENCE"):
                lines.append(line)
        blocks.append(lines)
    return blocks


_LMST_TAG = re.compile(r"^@\s*(?:sol\s+\d+\s+)?(\d{1,2}:\d{2}(?::\d{2})?\s+LMST)", re.I)


def validation_text(n_lines: int, first_sol: int = 100) -> str:
    """A sequence of exactly ``n_lines`` lines: a header and the examples' commands over
    and over, each repetition of an example on a sol of its own (its LMST tags made
    ``@ sol N``), so the time tags never run backwards and the whole sequence is valid."""
    blocks = example_blocks()
    out = ["SEQUENCE validate_bench"]
    k = 0
    while len(out) < n_lines:
        sol = first_sol + k
        for line in blocks[k % len(blocks)]:
            out.append(_LMST_TAG.sub(rf"@ sol {sol} \1", line))
        k += 1
    return "\n".join(out[:n_lines]) + "\n"


def _rover_context() -> Any:
    """Spirit's ``ValidationContext`` as the upload route builds it (a server of its own on
    an in-memory database, clocks not started)."""
    from server.app import Server, ServerConfig

    server = Server.open(ServerConfig(database_url="sqlite://", start_clocks=False))
    try:
        return server.context(server.rovers[ROVER])
    finally:
        server.stop()


def measure_validation(n_lines: int = 10_000, repeats: int = 3) -> dict[str, Any]:
    """Median wall time of ``validate`` on ``n_lines`` lines, without and with a rover."""
    text = validation_text(n_lines)
    context = _rover_context()
    walls: list[float] = []
    walls_rover: list[float] = []
    errors = warnings = steps = 0
    for _ in range(repeats):
        start = time.perf_counter()
        result = validate(text)
        walls.append(time.perf_counter() - start)
        start = time.perf_counter()
        with_rover = validate(text, context)
        walls_rover.append(time.perf_counter() - start)
        errors, steps = len(result.errors), len(result.sequence.steps) if result.sequence else 0
        warnings = len(with_rover.warnings)
    return {
        "validate_10k_lines_s": statistics.median(walls),
        "validate_10k_lines_with_rover_s": statistics.median(walls_rover),
        "validate_lines": n_lines,
        "validate_steps": steps,
        "validate_errors": errors,
        "validate_warnings_with_rover": warnings,
        "validate_repeats": repeats,
    }


def measure_blank_lines(server: RunningServer, n_lines: int = BLANK_LINES) -> dict[str, Any]:
    """``n_lines`` blank lines then one command: validated, then uploaded to a paused rover
    (and cancelled), each timed from request to answer."""
    text = "\n" * n_lines + "NADIR_UPDATE\n"
    start = time.perf_counter()
    status, answer = server.request("POST", "/api/sequences/validate", text, timeout_s=300.0)
    validate_s = time.perf_counter() - start
    if status != 200 or not answer["valid"]:
        raise RuntimeError(f"blank lines: HTTP {status}: {str(answer)[:300]}")
    server.ok("POST", "/api/rovers/opportunity/clock", {"action": "pause"})
    start = time.perf_counter()
    status, answer = server.request(
        "POST", "/api/rovers/opportunity/sequences", text, timeout_s=300.0
    )
    upload_s = time.perf_counter() - start
    if status != 201:
        raise RuntimeError(f"blank lines upload: HTTP {status}: {str(answer)[:300]}")
    server.ok("DELETE", f"/api/sequences/{answer['id']}")
    return {
        "validate_100k_blank_lines_s": validate_s,
        "upload_100k_blank_lines_s": upload_s,
        "blank_lines": n_lines,
    }


def measure_stall(server: RunningServer, size_bytes: int = UPLOAD_BYTES) -> dict[str, Any]:
    """``GET /api/rovers`` polled from another thread while a ``size_bytes`` sequence is
    validated against Spirit: the p99 and max of its latency (module docstring)."""
    import threading

    per_line = len(validation_text(1000)) / 1000
    text = validation_text(int(size_bytes / per_line))
    while len(text.encode()) > size_bytes:
        text = validation_text(len(text.splitlines()) - 100)
    idle: list[float] = []  # the same polls with nothing validating: the machine's own noise
    for _ in range(STALL_IDLE_POLLS):
        t0 = time.perf_counter()
        server.ok("GET", "/api/rovers")
        idle.append(time.perf_counter() - t0)
        time.sleep(STALL_POLL_S)
    answer: list[tuple[int, Any]] = []

    def upload() -> None:
        answer.append(server.request("POST", f"/api/sequences/validate?rover={ROVER}", text, 600.0))

    latencies: list[float] = []
    thread = threading.Thread(target=upload)
    start = time.perf_counter()
    thread.start()
    time.sleep(0.02)  # the body on its way (a small one validates in a fraction of a second)
    while thread.is_alive():
        t0 = time.perf_counter()
        server.ok("GET", "/api/rovers")
        if thread.is_alive():  # only polls that overlapped the validation count
            latencies.append(time.perf_counter() - t0)
        time.sleep(STALL_POLL_S)
    thread.join()
    elapsed = time.perf_counter() - start
    status, body = answer[0]
    if status != 200:
        raise RuntimeError(f"1 MB validation: HTTP {status}: {str(body)[:300]}")
    lat_ms = np.asarray(latencies) * 1000.0
    have = lat_ms.size > 0
    return {
        "event_loop_stall_ms_during_upload": float(np.percentile(lat_ms, 99)) if have else math.nan,
        "event_loop_stall_max_ms": float(lat_ms.max()) if have else math.nan,
        "event_loop_stall_samples": int(lat_ms.size),
        "event_loop_idle_p99_ms": float(np.percentile(np.asarray(idle) * 1000.0, 99)),
        "upload_1mb_validate_s": elapsed,
        "upload_1mb_bytes": len(text.encode()),
    }


FIRST_SOL = 90  # before Spirit's start (sol 101): the rover's own frames do not mix in
SOLS = 7
DOWNLINK_CHANNEL = "tilt_est_deg"
TRUTH_CHANNEL = "attitude_error_deg"
TEMPLATE_SEQUENCE = (
    "SEQUENCE bench_channels\nARTICULATE_START\nWAIT duration_s=60\nARTICULATE_STOP\n"
    "DRIVE_STRAIGHT distance_m=3\n"
)
WRITE_BATCH = 5000
NO_3D = {"ROVEROPS_NO_3D": "1"}  # its start reads every stored frame (module docstring)
QUERY_TIMEOUT_S = 300.0  # the JSON path of before took about 30 s


def store_sols(url: str, every_s: float, sols: int = SOLS) -> int:
    """Store ``sols`` sols of the records of ``TEMPLATE_SEQUENCE`` from ``FIRST_SOL``, one
    every ``every_s`` (module docstring); how many."""
    from server.runtime import ROVERS
    from server.storage import BatchWriter, Store
    from sim.world.marsclock import MISSIONS, lmst_h_from_t_s, sol_number_t_s, t_s_for_sol_lmst

    mission = ROVERS[ROVER].mission
    t0 = t_s_for_sol_lmst(mission, FIRST_SOL, 0.0)
    t1 = t_s_for_sol_lmst(mission, FIRST_SOL + sols, 0.0)
    t_s = np.arange(t0, t1, every_s)
    t_s = t_s[(sol_number_t_s(mission, t_s) >= FIRST_SOL)]  # t0 may round to the sol before
    sol = sol_number_t_s(mission, t_s)
    lmst_h = lmst_h_from_t_s(t_s, MISSIONS[mission].lon_west_deg)
    session, commands = spirit_session(TEMPLATE_SEQUENCE)
    for command in commands:
        session.execute(command, label=command.describe())
    template = session.take_frames()
    store = Store(url)
    writer = BatchWriter(store)
    try:
        for start in range(0, len(t_s), WRITE_BATCH):
            downlinks, truths = [], []
            for i in range(start, min(start + WRITE_BATCH, len(t_s))):
                downlink, truth = template[i % len(template)]
                t = float(t_s[i])
                clock = {"t_s": t, "sol": int(sol[i]), "lmst_h": float(lmst_h[i])}
                downlinks.append({**downlink, **clock, "events": []})
                truths.append({**truth, "t_s": t, "events": []})
            writer.frames(ROVER, downlinks, truths)
            writer.flush()
    finally:
        writer.stop()
        store.close()
    return len(t_s)


def measure_channel_query(
    data_dir: Path, every_s: float | None = None, repeats: int = 3
) -> dict[str, Any]:
    """7 sols stored, then a channel of them queried through the server (module docstring)."""
    from server.app import data_dir_url
    from server.runtime import FRAME_EVERY_S

    started = time.perf_counter()
    rows = store_sols(data_dir_url(data_dir), FRAME_EVERY_S if every_s is None else every_s)
    store_s = time.perf_counter() - started
    walls: dict[str, list[float]] = {DOWNLINK_CHANNEL: [], TRUTH_CHANNEL: []}
    points = 0
    with running_server(data_dir, env=NO_3D) as server:
        for _ in range(repeats):
            for channel, wall in walls.items():
                path = f"/api/rovers/{ROVER}/channels/{channel}?sol_from={FIRST_SOL}"
                path += f"&sol_to={FIRST_SOL + SOLS - 1}"
                start = time.perf_counter()
                status, answer = server.request("GET", path, timeout_s=QUERY_TIMEOUT_S)
                wall.append(time.perf_counter() - start)
                if status != 200:
                    raise RuntimeError(f"GET {path}: HTTP {status}: {str(answer)[:300]}")
                if answer["frames"] != rows:
                    raise RuntimeError(f"{channel}: {answer['frames']} frames, {rows} stored")
                points = len(answer["values"])
    return {
        "channel_query_7_sols_s": statistics.median(walls[DOWNLINK_CHANNEL]),
        "channel_query_7_sols_truth_s": statistics.median(walls[TRUTH_CHANNEL]),
        "channel_rows_stored": rows,
        "channel_store_wall_s": store_s,
        "channel_points": points,
        "channel_repeats": repeats,
    }


# ---- the bench ------------------------------------------------------------------------------


def bench_server(
    ws_clients: int = 50,
    ws_window_s: float = 10.0,
    validate_lines: int = 10_000,
    validate_repeats: int = 3,
    drive_m: float = 100.0,
    hga_min: float = 15.0,
    blank_lines: int = BLANK_LINES,
    upload_bytes: int = UPLOAD_BYTES,
    sol_repeats: int = 3,
    channel_every_s: float | None = None,
) -> dict[str, Any]:
    """The server bench (module docstring); the defaults are the issue's figures, smaller
    ones make a quick run (the targets stay the issue's). The sol is measured
    ``sol_repeats`` times, each on a new server after its in-process reference, and its
    figures are medians (the overhead: the median of the pairs' differences). The 7 sols of
    the channel query hold a frame every ``channel_every_s`` (default: ``FRAME_EVERY_S``)."""
    if sol_repeats < 1:
        raise ValueError(f"sol_repeats: must be at least 1, got {sol_repeats}")
    sols: list[dict[str, Any]] = []
    metrics: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="roverops-bench-") as tmp:
        for k in range(sol_repeats - 1):  # the sol alone, each on a new server
            reference = measure_sol_in_process(drive_m, hga_min)
            data_dir = Path(tmp) / f"sol{k}"
            data_dir.mkdir()
            with running_server(data_dir) as server:
                sols.append(_paired(reference, measure_sol(server, drive_m, hga_min)))
        reference = measure_sol_in_process(drive_m, hga_min)
        started = time.perf_counter()
        with running_server(Path(tmp)) as server:  # the last sol, then everything else
            metrics["server_start_s"] = time.perf_counter() - started
            sols.append(_paired(reference, measure_sol(server, drive_m, hga_min)))
            metrics.update({key: _median([s[key] for s in sols]) for key in sols[0]})
            metrics["sol_repeats"] = sol_repeats
            metrics.update(measure_ws(server, ws_clients, ws_window_s))
            metrics.update(measure_blank_lines(server, blank_lines))
            metrics.update(measure_stall(server, upload_bytes))
        channels_dir = Path(tmp) / "channels"
        channels_dir.mkdir()
        metrics.update(measure_channel_query(channels_dir, channel_every_s))
    metrics.update(measure_validation(validate_lines, validate_repeats))
    return bench_result("server", metrics, TARGETS)
