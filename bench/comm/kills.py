"""A real ``roverops serve --comm mission`` killed (SIGKILL) during uplinks and passes, and
what it stored compared with a run of the same scenario that was never killed
(``bench.comm.compare``).

The scenario (``Scenario``) is Spirit from its start (sol 100, 08:33 LMST) to the sol after,
its clock at max speed: there the runtime is deterministic (idle time skipped to what is due
next, the same steps every run), so two runs store the same rows and a difference is the
kills'. (At a finite speed the idle rover is stepped by wall time and no two runs agree.)

- The plan onboard at the start, ``onboard_plan``: a 30 m drive 2 minutes into sol 100's
  uplink window and a 20 m drive a minute into the first relay pass after it (20:54 LMST).
  It is sent with the link instant (``PUT .../comm/mode`` to ``instant`` and back), as if it
  had gone up on an earlier sol, so that the rover has something to do while the next rises.
- The next plan, ``uplinked_plan``: sent across light time at the start, it goes up at 09:00
  LMST and reaches the rover 17 minutes later, during the first drive; a 20 m drive a
  minute into the first relay pass of sol 101 (07:39 LMST).

Until the rover reports that a plan ended, the operators wait for it and at max speed the
clock skips on from one thing the link brings to the next. Once the report of the last has
come down (about 08:40 LMST of sol 101) nothing is awaited and the clock runs in real time
(``GET /api/rovers`` reads an effective speed of 1): nothing more comes down for hours, so
a run ends there (``_until_idle``) with what it stored settled, the same in every run.

The bench sees the rover's clock (``GET /api/rovers``), never what the rover does: the
server shows the ground's knowledge. At max speed the clock stands at a step's start while
the rover computes it, and at an uplink's arrival when the link hands it on. (A kill at a
random moment would land in the drives: a sol takes about a second.) Kills come at
triggers (``Trigger``), in the scenario's order:

- ``drive``: the rover computes a drive (0.5-3 s of wall time) with its clock at the drive's
  start, inside the uplink's flight or a relay pass; the kill comes a random moment later,
  up to ``KILL_SPREAD`` times as long as that drive took in the reference run: mostly while
  it computes, sometimes while its telemetry is played out, sent and stored. The server
  restarts from its last checkpoint, before the drive, so the drive is met again until it
  has had its kills.
- ``onboard``: the uplinked plan reaches the rover (the clock reaches its arrival, the
  ``received`` stage of the reference run); the kill comes a random moment up to
  ``ONBOARD_SPREAD_S`` later, around the server's next writes (the writer commits every
  0.5 s, the clock checkpoints every second).
- ``stored``: the moment a stage (the uplink radiated) or a sequence status (a report a pass
  brought down) reaches the database, read beside the server (WAL: a reader never blocks
  it), as ``bench restart`` does: the kill comes at once, when what goes with that row may
  still wait in the server's writer.

Half the kills (rounded up) are the uplink's (its flight's drive, onboard, radiated, in
turn), the rest the passes' (their reports stored, their drives, in the order they come).
A kill whose trigger has passed goes to the next trigger of its kind.
"""

from __future__ import annotations

import contextlib
import math
import random
import signal
import statistics
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bench.comm.checks import Stored, stage_faults
from bench.comm.compare import compare, examples
from bench.server_process import RunningServer, running_server, upload
from server.rovers import ROVERS
from server.storage import Store
from sim.comm.plan import CommPlan
from sim.comm.windows import comm_windows
from sim.world.marsclock import (
    SOL_S,
    get_mission,
    lmst_h_from_t_s,
    sol_number_t_s,
    t_s_for_sol_lmst,
    utc_to_t_s,
)

ROVER = "spirit"
ENV = {"ROVEROPS_NO_3D": "1", "ROVEROPS_COMM": "mission"}
ONBOARD, UPLINKED = "onboard_plan", "uplinked_plan"
UPLINK_DRIVE_M = 30.0  # ~800 s: it ends before the next plan reaches the rover
PASS_DRIVE_M = 20.0
INTO_UPLINK_S = 120.0  # the first drive starts this long after the uplink window opens
INTO_PASS_S = 60.0
KILL_SPREAD = 1.3  # a drive's kill comes up to this many times its wall time after it starts
ONBOARD_SPREAD_S = 1.2  # an onboard kill comes up to this long after the uplink arrived
POLL_S = 0.02  # wall seconds between looks at the rover's clock
DB_POLL_S = 0.002  # and at its database
TRIGGER_TIMEOUT_S = 120.0  # wall seconds to wait for a trigger
RUN_TIMEOUT_S = 300.0
SEED = 23
STATUS_ORDER = {"queued": 0, "running": 1, "completed": 2, "failed": 2, "cancelled": 2}


@dataclass(frozen=True)
class Trigger:
    """When a kill comes (module docstring): the rover computing the drive that starts at
    ``t_s`` (``what == "drive"``); ``sequence`` reaching the rover (``"onboard"``);
    ``stage`` (a stage name, or ``status:<status>``) of ``sequence`` stored (``"stored"``).
    ``kind``: uplink or pass; ``order``: the uplink's triggers take their kills in this
    order (lowest first)."""

    kind: str
    what: str
    t_s: float = math.nan
    sequence: str = ""
    stage: str = ""
    order: int = 0

    def text(self) -> str:
        if self.what == "drive":
            return f"{self.kind} drive at {self.t_s:.0f}"
        if self.what == "onboard":
            return f"{self.kind} {self.sequence} onboard"
        return f"{self.kind} {self.sequence} {self.stage} stored"


@dataclass(frozen=True)
class Scenario:
    """The two plans, the triggers in their order, and when the last report is due."""

    onboard: str
    uplinked: str
    triggers: tuple[Trigger, ...]
    end_s: float  # the last drive's start: a run ends at rest after it (``_until_idle``)


def _tag(t_s: float) -> tuple[str, float]:
    """The time tag of the whole LMST second at or after ``t_s``, and its time."""
    lon_west = get_mission(ROVER).lon_west_deg
    sol = int(sol_number_t_s(ROVER, t_s))
    seconds = math.ceil(float(lmst_h_from_t_s(t_s, lon_west)) * 3600.0 - 1e-6)
    h, rest = divmod(seconds, 3600)
    tag = f"@ sol {sol} {h:02d}:{rest // 60:02d}:{rest % 60:02d} LMST"
    return tag, t_s_for_sol_lmst(ROVER, sol, seconds / 3600.0)


def scenario(plan: CommPlan | None = None) -> Scenario:
    """The scenario from Spirit's start, on ``plan``'s windows (module docstring)."""
    plan = plan or CommPlan()
    site = get_mission(ROVER)
    t0 = utc_to_t_s(ROVERS[ROVER].start_utc)
    windows = comm_windows(site.lat_deg, site.lon_east_deg, plan, t0, t0 + 2.5 * SOL_S)
    up = next(w for w in windows if w.kind == "uplink" and w.start_t_s > t0)
    relays = [w for w in windows if w.kind == "relay" and w.start_t_s > up.end_t_s]
    (up_tag, up_t), (p1_tag, p1_t), (p2_tag, p2_t) = (
        _tag(up.start_t_s + INTO_UPLINK_S),
        _tag(relays[0].start_t_s + INTO_PASS_S),
        _tag(relays[1].start_t_s + INTO_PASS_S),
    )
    onboard = (
        f"SEQUENCE {ONBOARD}\n{up_tag} DRIVE_STRAIGHT distance_m={UPLINK_DRIVE_M:g}\n"
        f"{p1_tag} DRIVE_STRAIGHT distance_m={PASS_DRIVE_M:g}\n"
    )
    uplinked = f"SEQUENCE {UPLINKED}\n{p2_tag} DRIVE_STRAIGHT distance_m={PASS_DRIVE_M:g}\n"
    triggers = (
        Trigger("uplink", "stored", sequence=UPLINKED, stage="radiated", order=2),
        Trigger("uplink", "drive", up_t),
        Trigger("uplink", "onboard", sequence=UPLINKED, order=1),
        Trigger("pass", "stored", sequence=ONBOARD, stage="status:running"),
        Trigger("pass", "drive", p1_t),
        Trigger("pass", "stored", sequence=ONBOARD, stage="status:completed"),
        Trigger("pass", "drive", p2_t),
        Trigger("pass", "stored", sequence=UPLINKED, stage="status:running"),
    )
    return Scenario(onboard, uplinked, triggers, p2_t)


def quotas(kills: int, triggers: tuple[Trigger, ...]) -> list[int]:
    """Kills per trigger: half (rounded up) the uplink's, the rest the passes', each
    trigger of a kind one in turn, by ``order`` then as they come.

    >>> quotas(3, (Trigger("uplink", "onboard", order=1), Trigger("uplink", "drive"),
    ...            Trigger("pass", "drive")))
    [1, 1, 1]
    """
    quota = [0] * len(triggers)
    for kind, n in (("uplink", (kills + 1) // 2), ("pass", kills // 2)):
        mine = sorted((i for i, t in enumerate(triggers) if t.kind == kind),
                      key=lambda i: triggers[i].order)  # fmt: skip
        for k in range(n):
            quota[mine[k % len(mine)]] += 1
    return quota


# ---- one run ----------------------------------------------------------------------------------


@dataclass
class Run:
    """One run of the scenario: its database, its kills and how long the drives took."""

    data_dir: Path
    kills: list[tuple[Trigger, float]] = field(default_factory=list)  # (trigger, delay_s)
    missed: list[Trigger] = field(default_factory=list)  # triggers that never came
    drive_wall_s: dict[float, float] = field(default_factory=dict)  # drive's t_s -> wall
    received_t_s: dict[str, float] = field(default_factory=dict)  # sequence -> onboard at
    restart_s: list[float] = field(default_factory=list)
    wall_s: float = 0.0

    @property
    def url(self) -> str:
        return f"sqlite:///{self.data_dir / 'roverops.db'}"


def _state(server: RunningServer) -> dict[str, Any]:
    """The rover's clock and what it executes (``GET /api/rovers``: without the frame, so
    that watching costs the server little)."""
    rovers: list[dict[str, Any]] = server.ok("GET", "/api/rovers")
    return next(r for r in rovers if r["rover"] == ROVER)


def _prepare(server: RunningServer, scene: Scenario) -> None:
    """Both plans sent (module docstring), the clock at max speed."""
    for rover in ROVERS:
        server.ok("POST", f"/api/rovers/{rover}/clock", {"action": "pause"})
    server.ok("PUT", f"/api/rovers/{ROVER}/comm/mode", {"mode": "instant"})
    upload(server, ROVER, scene.onboard)
    server.ok("PUT", f"/api/rovers/{ROVER}/comm/mode", {"mode": "mission"})
    upload(server, ROVER, scene.uplinked)
    server.ok("POST", f"/api/rovers/{ROVER}/clock", {"action": "resume", "speed": "max"})


def _computing(state: dict[str, Any], t_s: float) -> bool:
    """Whether the rover's clock stands at ``t_s``, a drive's start (it computes it)."""
    return abs(float(state["t_s"]) - t_s) < 0.5


def _watch_drive(server: RunningServer, trigger: Trigger) -> float | None:
    """Wait until the rover computes the trigger's drive: the wall time then, or ``None``
    if the rover is past it."""
    deadline = time.monotonic() + TRIGGER_TIMEOUT_S
    while time.monotonic() < deadline:
        state = _state(server)
        if _computing(state, trigger.t_s):
            return time.monotonic()
        if float(state["t_s"]) > trigger.t_s + 1.0:
            return None
        time.sleep(POLL_S)
    return None


def _watch_onboard(server: RunningServer, arrival_t_s: float) -> bool | None:
    """Wait until the rover's clock reaches ``arrival_t_s``: True then, ``None`` if it was
    past it when the watch began."""
    if float(_state(server)["t_s"]) >= arrival_t_s:
        return None
    deadline = time.monotonic() + TRIGGER_TIMEOUT_S
    while time.monotonic() < deadline:
        if float(_state(server)["t_s"]) >= arrival_t_s:
            return True
        time.sleep(POLL_S / 4)
    return None


def _stored(store: Store, trigger: Trigger) -> bool:
    """Whether the trigger's stage (or status, or a later one) is in the database."""
    found = next((s for s in store.list_sequences(ROVER) if s["name"] == trigger.sequence), None)
    if found is None:
        return False
    if trigger.stage.startswith("status:"):
        wanted = STATUS_ORDER[trigger.stage.removeprefix("status:")]
        return STATUS_ORDER.get(str(found["status"]), 0) >= wanted
    return any(g["stage"] == trigger.stage for g in found["stages"] or [])


def _watch_stored(store: Store, trigger: Trigger) -> bool | None:
    """Wait until the trigger's row is stored: True then, ``None`` if it was already."""
    if _stored(store, trigger):
        return None
    deadline = time.monotonic() + TRIGGER_TIMEOUT_S
    while time.monotonic() < deadline:
        if _stored(store, trigger):
            return True
        time.sleep(DB_POLL_S)
    return None


def _until_idle(server: RunningServer, t_s: float, deadline: float) -> None:
    """Wait until the rover's clock is past ``t_s`` and runs in real time (nothing is
    awaited across the link: module docstring), then pause it."""
    while True:
        state = _state(server)
        if float(state["t_s"]) > t_s and state["effective_speed"] == 1:
            break
        if time.monotonic() > deadline:
            raise RuntimeError(f"the rover did not come to rest after {t_s:.0f} in time")
        time.sleep(POLL_S * 5)
    server.ok("POST", f"/api/rovers/{ROVER}/clock", {"action": "pause"})


def reference_run(data_dir: Path, scene: Scenario) -> Run:
    """The scenario without kills; how long each drive took (wall)."""
    run = Run(data_dir)
    started = time.monotonic()
    with running_server(data_dir, env=ENV) as server:
        _prepare(server, scene)
        for trigger in scene.triggers:
            if trigger.what != "drive":
                continue
            began = _watch_drive(server, trigger)
            if began is None:
                run.missed.append(trigger)
                continue
            while _computing(_state(server), trigger.t_s):
                time.sleep(POLL_S)
            run.drive_wall_s[trigger.t_s] = time.monotonic() - began
        _until_idle(server, scene.end_s, started + RUN_TIMEOUT_S)
    run.wall_s = time.monotonic() - started
    for seq in Stored.read(run.url, ROVER).sequences:
        found = [g["t_s"] for g in seq["stages"] or [] if g["stage"] == "received"]
        if found:
            run.received_t_s[str(seq["name"])] = float(found[0])
    return run


def kill_run(
    data_dir: Path,
    scene: Scenario,
    kills: int,
    reference: Run,
    seed: int,
    spread: float = KILL_SPREAD,
) -> Run:
    """The scenario with ``kills`` SIGKILLs at its triggers (module docstring); a drive's
    kill up to ``spread`` times its wall time after it starts."""
    rng = random.Random(seed)
    run = Run(data_dir)
    started = time.monotonic()
    quota = quotas(kills, scene.triggers)
    store = Store(run.url)
    with contextlib.ExitStack() as stack:
        stack.callback(store.close)
        server = stack.enter_context(running_server(data_dir, env=ENV))
        _prepare(server, scene)
        for i, trigger in enumerate(scene.triggers):
            kind = trigger.kind
            while quota[i] > 0:
                if trigger.what == "drive":
                    came = _watch_drive(server, trigger) is not None
                    longest = spread * reference.drive_wall_s.get(trigger.t_s, 1.0)
                    delay = rng.uniform(0.0, longest)
                elif trigger.what == "onboard":
                    arrival = reference.received_t_s.get(trigger.sequence, math.inf)
                    came = _watch_onboard(server, arrival) is not None
                    delay = rng.uniform(0.0, ONBOARD_SPREAD_S)
                else:
                    came, delay = _watch_stored(store, trigger) is not None, 0.0
                if not came:  # passed: its kills go to the next trigger of its kind
                    run.missed.append(trigger)
                    later = [j for j in range(i + 1, len(quota)) if scene.triggers[j].kind == kind]
                    if later:
                        quota[later[0]] += quota[i]
                    quota[i] = 0
                    break
                time.sleep(delay)
                server.process.send_signal(signal.SIGKILL)
                server.process.wait(timeout=60.0)
                stack.close()
                stack.callback(store.close)
                run.kills.append((trigger, delay))
                quota[i] -= 1
                began = time.monotonic()
                server = stack.enter_context(running_server(data_dir, env=ENV))
                run.restart_s.append(time.monotonic() - began)
        _until_idle(server, scene.end_s, started + RUN_TIMEOUT_S + 30.0 * kills)
    run.wall_s = time.monotonic() - started
    return run


# ---- the figures ------------------------------------------------------------------------------


def _sum(found: dict[str, dict[str, int]], what: str) -> int:
    return sum(v[what] for v in found.values())


def measure_kills(kills: int, seed: int = SEED, spread: float = KILL_SPREAD) -> dict[str, Any]:
    """The reference run and the killed run (module docstring), compared; ``spread``: a
    drive's kill comes up to this many times the drive's wall time after it starts."""
    scene = scenario()
    with tempfile.TemporaryDirectory(prefix="roverops-bench-comm-kills-") as tmp:
        root = Path(tmp)
        for name in ("reference", "killed"):
            (root / name).mkdir()
        reference = reference_run(root / "reference", scene)
        killed = kill_run(root / "killed", scene, kills, reference, seed, spread)
        ref_rows = Stored.read(reference.url, ROVER)
        got_rows = Stored.read(killed.url, ROVER)
    found = compare(ref_rows, got_rows)
    restart_s = statistics.median(killed.restart_s) if killed.restart_s else math.nan
    site = get_mission(ROVER)
    t0 = utc_to_t_s(ROVERS[ROVER].start_utc)
    windows = comm_windows(site.lat_deg, site.lon_east_deg, CommPlan(), t0, scene.end_s)
    return {
        "kills": len(killed.kills),
        "kills_mid_uplink": sum(1 for t, _ in killed.kills if t.kind == "uplink"),
        "kills_mid_pass": sum(1 for t, _ in killed.kills if t.kind == "pass"),
        "kills_at_drives": sum(1 for t, _ in killed.kills if t.what == "drive"),
        "kill_mid_pass_lost": _sum(found, "lost"),
        # stored more often than in the reference, or not in it at all: what a command run
        # twice leaves (its second run's frames, events and times)
        "kill_mid_pass_duplicated": _sum(found, "duplicated") + _sum(found, "extra"),
        "kill_reference_frames": len(ref_rows.frames),
        "kill_reruns": sum(int(c["reruns"]) for c in got_rows.commands),
        "early_arrivals_kills": len(ref_rows.early()) + len(got_rows.early()),
        "uplink_faults_kills": len(stage_faults(ref_rows.sequences, windows))
        + len(stage_faults(got_rows.sequences, windows)),
        "kill_reference_wall_s": reference.wall_s,
        "kill_run_wall_s": killed.wall_s,
        "kill_restart_median_s": restart_s,
        "details_kills": {
            "by_kind": found,
            "examples": examples(ref_rows, got_rows),
            "kills": [f"{t.text()} +{d:.3f} s" for t, d in killed.kills],
            "missed": [t.text() for t in killed.missed + reference.missed],
            "drive_wall_s": {f"{k:.0f}": round(v, 3) for k, v in reference.drive_wall_s.items()},
        },
    }
