"""``channel_query_7_sols_s`` of ``roverops bench server``: one channel over 7 stored sols.

The 7 sols are stored straight through the server's storage (``server.storage.Store`` and
its ``BatchWriter``, as the runtime's storage sink writes) before the server starts: the
real frames (downlink and truth records) of a session made as the server makes Spirit's
(its site, seed, start and ``FRAME_EVERY_S``) articulating and driving, repeated and
shifted in time to one frame every ``every_s`` seconds over sols ``FIRST_SOL`` to
``FIRST_SOL + 6`` (each copy's ``t_s``, ``sol`` and ``lmst_h`` made anew from its time on
Spirit's clock; its events dropped, so the events table stays as a sol's). At the default
``every_s`` of ``FRAME_EVERY_S`` that is a frame for every simulated second of 7 sols:
the most the server keeps (``server.runtime``: one frame per simulated second of
activity), about 621,000 rows.

The query is ``GET /api/rovers/spirit/channels/{channel}?sol_from=..&sol_to=..`` through
the real server, timed from request to answer, the median of ``repeats``:
``channel_query_7_sols_s`` for a downlink channel (``DOWNLINK_CHANNEL``) and
``channel_query_7_sols_truth_s`` for a truth channel (``TRUTH_CHANNEL``), reported
without a target. ``channel_rows_stored`` is how many frames were stored and
``channel_store_wall_s`` how long storing them took. The server runs without its 3D view
(``ROVEROPS_NO_3D``): the view's start reads the whole stored history of its rover
(``server.scene3d``), which is not what this figure measures.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.server_process import running_server

ROVER = "spirit"
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


def template_frames() -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """The (downlink, truth) records of Spirit's session running ``TEMPLATE_SEQUENCE``."""
    from sequences.validate import validate
    from server.runtime import FRAME_EVERY_S, ROVERS
    from sim.loop.session import RoverSession

    result = validate(TEMPLATE_SEQUENCE)
    assert result.sequence is not None, result.errors
    spec = ROVERS[ROVER]
    session = RoverSession(
        spec.site, spec.seed, spec.start_utc, frame_every_s=FRAME_EVERY_S, estimators=("sapp",)
    )
    for step in result.sequence.steps:
        session.execute(step.command, label=step.command.describe())
    return session.take_frames()


def store_sols(url: str, every_s: float, sols: int = SOLS) -> int:
    """Store ``sols`` sols of Spirit's frames from ``FIRST_SOL`` at one every ``every_s``
    (module docstring); how many."""
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
    template = template_frames()
    store = Store(url)
    writer = BatchWriter(store)
    try:
        for start in range(0, len(t_s), WRITE_BATCH):
            downlinks, truths = [], []
            for i in range(start, min(start + WRITE_BATCH, len(t_s))):
                downlink, truth = template[i % len(template)]
                t = float(t_s[i])
                downlinks.append(
                    {**downlink, "t_s": t, "sol": int(sol[i]), "lmst_h": float(lmst_h[i]),
                     "events": []}
                )  # fmt: skip
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
    """7 sols stored in a new server's database, then one channel of them queried
    ``repeats`` times through the server, for a downlink and a truth channel."""
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
                path = (
                    f"/api/rovers/{ROVER}/channels/{channel}"
                    f"?sol_from={FIRST_SOL}&sol_to={FIRST_SOL + SOLS - 1}"
                )
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
