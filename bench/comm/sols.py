"""Sols of Spirit across light time through the server's runtime, in-process, at max speed.

A ``Server`` (``server.state``) on a SQLite file, Spirit's link in ``mission`` mode
(``ServerConfig(comm="mission")``), its clock at max speed (idle time skipped to what is
due next, so a sol takes about a second). Each sol's drive goes up as operators send it:
one sequence a sol (``drive_sequence``: ``@ 11:00 LMST`` a NADIR_UPDATE, then a drive),
the first uploaded at the start (08:33 LMST of sol 100, before that sol's 09:00 uplink
window), each next one once the rover's clock is past the window that carried the one
before (in practice while that sol's drive is computed: the clock stands at its start), so
it goes up in the next sol's window. The sequence of the sol after the last is sent too:
while a sequence is on the ground, on its way or onboard unreported, the operators wait for
it and the clock skips on from one thing the link brings to the next (with nothing on its
way it would run in real time).

A ``LinkTap`` on the runtime's link records what the link itself did (every product on the
ground, every uplink radiated); the database is read after the server stopped. What one run
gives (``SolsRun``) is judged by ``sols_metrics`` and ``overflow_metrics``.
"""

from __future__ import annotations

import contextlib
import math
import statistics
import tempfile
import time
from collections import Counter
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.comm.checks import LinkTap, Stored, early_sent, stage_faults, uplink_faults
from sequences.validate import validate
from server.runtime import RoverRuntime
from server.state import Server, ServerConfig
from server.storage.engine import data_dir_url
from sim.comm.link import CommLink
from sim.comm.plan import CommPlan
from sim.comm.windows import Window, comm_windows
from sim.world.marsclock import SOL_S, get_mission

ROVER = "spirit"
SOLS = 3
DRIVE_M = 20.0
DRIVE_LMST = "11:00"
AFTER_WINDOW_S = 60.0  # the next sol's sequence is sent this long after a window closes
TAIL_S = 3_600.0  # the run goes on this long past its sols: the last pass's data comes down
POLL_S = 0.005  # the bench watches the rover's clock this often (wall)
RUN_TIMEOUT_S = 300.0  # wall seconds a run may take at most
OVERFLOW_STORE_MBIT = 0.1  # a store far too small for a drive's telemetry


def drive_sequence(index: int, drive_m: float = DRIVE_M) -> str:
    """Sol ``index``'s sequence: at 11:00 LMST, after the uplink window, the attitude
    from the accelerometers, then a drive."""
    return (
        f"SEQUENCE sol_drive_{index}\n"
        f"@ {DRIVE_LMST} LMST NADIR_UPDATE\n"
        f"DRIVE_STRAIGHT distance_m={drive_m:g}\n"
    )


@dataclass
class SolsRun:
    """What one in-process run left behind (module docstring)."""

    t0_s: float  # the rover's clock at the start
    span_end_s: float  # the end of the sols measured
    plan: CommPlan
    windows: list[Window]  # the link's windows over the run
    passes: list[dict[str, Any]]  # what the ground tallied of each pass (MissionLink.passes)
    tap: LinkTap
    stored: Stored
    made: int  # products the store numbered (frames, reports, gaps)
    held_ids: list[int]  # in the store at the end
    falling_ids: list[int]  # sent, not yet on the ground at the end
    dropped: int  # the store's drops
    gaps_held: list[dict[str, Any]]  # gap accounts still in the store or on their way
    uploads: list[int] = field(default_factory=list)
    wall_s: float = 0.0


def _upload(server: Server, runtime: RoverRuntime, text: str) -> int:
    """As ``POST /api/rovers/{rover}/sequences`` does it: validate, store, queue."""
    result = validate(text)
    if result.sequence is None:
        raise ValueError(f"the bench's sequence does not validate: {result.errors}")
    name = result.sequence.name or "sequence"
    sequence_id = server.store.add_sequence(ROVER, name, text, "text", "queued", [], [], [])
    runtime.enqueue(sequence_id, result.sequence)
    return sequence_id


def _until(runtime: RoverRuntime, t_s: float, deadline: float) -> None:
    while runtime.t_s < t_s:
        if time.monotonic() > deadline:
            raise RuntimeError(f"the rover's clock did not reach {t_s:.0f} in time")
        time.sleep(POLL_S)


@contextlib.contextmanager
def _server(data_dir: Path) -> Iterator[Server]:
    config = ServerConfig(
        database_url=data_dir_url(data_dir),
        start_clocks=False,  # Spirit's alone is started; Opportunity stays at its start
        comm="mission",
        validation_processes=0,
    )
    server = Server.open(config)
    server.start()
    try:
        yield server
    finally:
        server.stop()


def run_sols(
    sols: int = SOLS,
    drive_m: float = DRIVE_M,
    plan_changes: Mapping[str, float] | None = None,
) -> SolsRun:
    """``sols`` sols with a drive each (module docstring); ``plan_changes`` applied to the
    comm plan first, as ``PUT /api/rovers/spirit/comm/plan`` applies them."""
    site = get_mission(ROVER)
    with tempfile.TemporaryDirectory(prefix="roverops-bench-comm-") as tmp:
        with _server(Path(tmp)) as server:
            runtime = server.rovers[ROVER]
            if plan_changes:
                runtime.comm.request(None, runtime.comm.plan.replaced(plan_changes))
            mission = runtime.comm.mission
            assert mission is not None
            tap = LinkTap()
            tap.attach(mission.link)
            plan = mission.plan
            t0 = runtime.t_s
            span_end = t0 + sols * SOL_S
            windows = comm_windows(site.lat_deg, site.lon_east_deg, plan, t0, span_end + SOL_S)
            uplinks = [w for w in windows if w.kind == "uplink" and w.end_t_s > t0]
            started = time.monotonic()
            deadline = started + RUN_TIMEOUT_S
            uploads = [_upload(server, runtime, drive_sequence(0, drive_m))]
            runtime.set_clock(speed=math.inf)
            runtime.start()
            for k in range(1, sols + 1):
                _until(runtime, uplinks[k - 1].end_t_s + AFTER_WINDOW_S, deadline)
                if runtime.t_s >= uplinks[k].start_t_s:
                    raise RuntimeError(f"sol {k}'s sequence missed its window: sent too late")
                uploads.append(_upload(server, runtime, drive_sequence(k, drive_m)))
            _until(runtime, span_end + TAIL_S, deadline)
            runtime.set_clock(running=False)
            _settle(runtime, deadline)
            wall_s = time.monotonic() - started
            link = mission.link  # the tap's link: a runtime that is not restored keeps it
            found = _store_account(link)
            passes = [dict(p) for p in mission.passes.values()]
            url = server.config.database_url
        stored = Stored.read(url, ROVER)
    return SolsRun(t0, span_end, plan, windows, passes, tap, stored, **found, uploads=uploads,
                   wall_s=wall_s)  # fmt: skip


def _settle(runtime: RoverRuntime, deadline: float) -> None:
    """Wait until a pause has taken effect (the clock reads the same twice)."""
    while True:
        before = runtime.t_s
        time.sleep(0.2)
        if runtime.t_s == before:
            return
        if time.monotonic() > deadline:
            raise RuntimeError("the rover's clock did not stop")


def _store_account(link: CommLink) -> dict[str, Any]:
    state = link.store.state()
    held = state["products"]
    falling = [s.product for s in link.falling]
    return {
        "made": int(state["next_id"]) - 1,
        "held_ids": [int(p["id"]) for p in held],
        "falling_ids": [p.id for p in falling],
        "dropped": int(state["stats"]["dropped"]),
        "gaps_held": [dict(p["payload"]) for p in held if p["kind"] == "gap"]
        + [dict(p.payload) for p in falling if p.kind == "gap"],
    }


# ---- the figures ----------------------------------------------------------------------------


def _in_span(run: SolsRun, t_s: float) -> bool:
    return run.t0_s <= t_s < run.span_end_s


def lost_products(run: SolsRun) -> dict[str, int]:
    """Products unaccounted for: made but neither on the ground, in the store, on their way
    down nor counted as dropped; products on the ground twice; frames and command reports
    on the ground but not stored (by ``t_s``; by sequence and step)."""
    delivered = Counter(s.product.id for s in run.tap.sent)
    accounted = set(delivered) | set(run.held_ids) | set(run.falling_ids)
    frames = {s.product.t_s for s in run.tap.sent if s.product.kind == "frame"}
    reports = {
        (int(p["sequence_id"]), int(p["step_index"]))
        for p in (s.product.payload for s in run.tap.sent if s.product.kind == "report")
        if p.get("type") == "command"
    }
    stored_times = [t for t, _r in run.stored.frames]
    stored_frames = set(stored_times)
    stored_steps = {(int(c["sequence_id"]), int(c["step_index"])) for c in run.stored.commands}
    return {
        "unaccounted": max(0, run.made - len(accounted) - run.dropped),
        "delivered_twice": sum(n - 1 for n in delivered.values()),
        "frames_not_stored": len(frames - stored_frames),
        "reports_not_stored": len(reports - stored_steps),
        "frames_stored_twice": sum(n - 1 for n in Counter(stored_times).values()),
    }


def sols_metrics(run: SolsRun, sols: int) -> dict[str, Any]:
    """Passes, data volume and the checks of one ``run_sols`` run."""
    relay = [w for w in run.windows if w.kind == "relay" and _in_span(run, w.start_t_s)]
    down = [w for w in run.windows if w.kind in ("relay", "dte") and _in_span(run, w.start_t_s)]
    capacity = {(w.kind, round(w.start_t_s, 3)): w.capacity_mbit for w in down}
    passes = [p for p in run.passes if _in_span(run, float(p["start_t_s"]))]
    tallied_mbit = sum(float(p["bits"]) for p in passes) / 1e6
    tapped_mbit = sum(s.product.bits for s in run.tap.sent if _in_span(run, s.pass_start_t_s)) / 1e6
    over = [
        p for p in passes
        if float(p["bits"]) / 1e6 > capacity.get((p["via"], round(float(p["start_t_s"]), 3)), 0.0)
    ]  # fmt: skip
    lost = lost_products(run)
    early = early_sent(run.tap.sent, run.plan.relay_latency_s) + run.stored.early()
    uplinks = uplink_faults(run.tap.radiated, run.plan.uplink_rate_bps, run.windows)
    uplinks += stage_faults(run.stored.sequences, run.windows)
    drives = [c for c in run.stored.commands if str(c["command"]).startswith("DRIVE")]
    minutes = [w.duration_s / 60.0 for w in relay]
    return {
        "sols": sols,
        "sols_wall_s": run.wall_s,
        "relay_passes_per_sol": len(relay) / sols,
        "relay_pass_minutes_median": statistics.median(minutes) if minutes else math.nan,
        "downlink_passes_used": len(passes),
        "downlinked_mbit_per_sol": tallied_mbit / sols,
        "downlink_capacity_mbit_per_sol": sum(capacity.values()) / sols,
        "downlinked_mbit_le_capacity": bool(not over and tallied_mbit <= sum(capacity.values())),
        "downlinked_tally_agrees": bool(abs(tallied_mbit - tapped_mbit) < 1e-9),
        "drives_completed": sum(1 for c in drives if c["status"] == "completed"),
        "products_made": run.made,
        "products_on_ground": len(run.tap.sent),
        "frames_stored": len(run.stored.frames),
        "early_arrivals_sols": len(early),
        "uplink_faults_sols": len(uplinks),
        "products_lost_sols": sum(v for k, v in lost.items() if k != "delivered_twice"),
        "products_twice_sols": lost["delivered_twice"] + lost["frames_stored_twice"],
        "details_sols": {"early": early[:5], "uplinks": uplinks[:5], "lost": lost},
    }


def overflow_metrics(run: SolsRun) -> dict[str, Any]:
    """The store set too small: how many of its drops a gap names (on the ground, or still
    in the store or on its way), and what was lost beside the drops."""
    on_ground = [s.product.payload for s in run.tap.sent if s.product.kind == "gap"]
    named_ground = sum(int(g["count"]) for g in on_ground)
    named = named_ground + sum(int(g["count"]) for g in run.gaps_held)
    lost = lost_products(run)
    early = early_sent(run.tap.sent, run.plan.relay_latency_s) + run.stored.early()
    return {
        "overflow_store_mbit": run.plan.store_capacity_mbit,
        "overflow_dropped": run.dropped,
        "overflow_gaps": len(on_ground) + len(run.gaps_held),
        "overflow_accounted_pct": 100.0 * named / run.dropped if run.dropped else math.nan,
        "overflow_on_ground_pct": 100.0 * named_ground / run.dropped if run.dropped else math.nan,
        "early_arrivals_overflow": len(early),
        "products_lost_overflow": sum(v for k, v in lost.items() if k != "delivered_twice"),
        "products_twice_overflow": lost["delivered_twice"] + lost["frames_stored_twice"],
    }


def measure_sols(sols: int = SOLS, drive_m: float = DRIVE_M) -> dict[str, Any]:
    """The sols run and the overflow run (one sol, the store ``OVERFLOW_STORE_MBIT``)."""
    metrics = sols_metrics(run_sols(sols, drive_m), sols)
    overflow = run_sols(1, drive_m, {"store_capacity_mbit": OVERFLOW_STORE_MBIT})
    return {**metrics, **overflow_metrics(overflow)}
