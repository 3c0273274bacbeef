"""``POST /api/rovers/{rover}/vo-advice``: the pointing advisor (``server.terrain.advisor``)
for a planned VO drive, as an operator asks it from the sequence editor.

The drive is a command line (``DRIVE_STRAIGHT distance_m=3 vo=on``) or a line of a sequence
text. It starts from the rover's last *reported* pose (its newest downlink record on the
ground, never the live session) moved by the planned motions of the drive commands before
that line in the sequence (their nominal paths; a ``DRIVE_TO`` before it cannot be planned
so, and is refused). The Sun is the onboard ephemeris's (``estimation.ivp``) at the rover's
clock now. The map is the rover's ground map (``server.terrain.feed``: the orbital product
refined by the pairs that came down) when the drive lies on it, else a level map at the
rover's reported height with no measured texture (the advice then rests on geometry alone:
overlap, the scale change between steps and the rover's shadow; it says so in ``map``).
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.ndimage import gaussian_filter
from scipy.spatial.transform import Rotation

from estimation.ivp import sun_ll
from sequences import commands as cmd
from sequences.language import parse_any
from server.access.auth import Operator
from server.api.deps import (
    AUTH_ERRORS,
    BAD_REQUEST,
    NOT_FOUND,
    TOO_LARGE,
    RoverName,
    ServerDep,
    router,
)
from server.errors import InvalidError
from server.terrain.advisor import BODY_HEIGHT_M, Advice, PlannedDrive, advise
from server.terrain.feed import ground_feed
from server.terrain.ground_map import GroundMap
from server.validation.context import rover_site

LEVEL_MAP_HALF_M = 20.0  # the level map's reach around the rover
LEVEL_MAP_CELL_M = 0.5
MAX_TEXT_CHARS = 100_000
ORBITAL_SMOOTHING_M = 3.0  # the unmeasured ground's smoothing for the advisor (planning_surface)


class AdviceRefusedError(InvalidError):
    """A request the advisor cannot answer (422, with the reason): not a drive, a line
    with no command, no reported pose yet, the Sun down."""


class AdviceBody(BaseModel):
    """A drive command's line (``command``), or a sequence ``text`` and the ``line`` (1-based)
    of its drive."""

    model_config = ConfigDict(extra="forbid", strict=True)
    command: str | None = Field(default=None, max_length=2000)
    text: str | None = Field(default=None, max_length=MAX_TEXT_CHARS)
    line: int | None = Field(default=None, ge=1, le=100_000)


class CandidateAnswer(BaseModel):
    az_deg: float
    el_deg: float
    features_min: float
    overlap_min: float
    shadow_max: float
    featureless_max: float
    ok: bool


class AdviceAnswer(BaseModel):
    """The candidates, the recommendation (null when none meets the rule's limits),
    ``arguments`` to put on the drive's line, the rule, and what the map was."""

    line: int | None
    command: str
    pairs: int
    recommended: CandidateAnswer | None
    arguments: str | None
    reason: str
    rule: str
    map: str
    candidates: list[CandidateAnswer]


def _candidate(c: Any) -> dict[str, Any]:
    return {k: getattr(c, k) for k in CandidateAnswer.model_fields}


def planned(command: cmd.Command) -> PlannedDrive | None:
    """The nominal path of a drive command (None for any other command)."""
    if isinstance(command, cmd.DriveStraight):
        return PlannedDrive("straight", distance_m=float(command.distance_m))
    if isinstance(command, cmd.DriveArc):
        return PlannedDrive("arc", radius_m=float(command.radius_m),
                            angle_deg=float(command.angle_deg))  # fmt: skip
    if isinstance(command, cmd.TurnInPlace):
        return PlannedDrive("turn", angle_deg=float(command.angle_deg))
    return None


def _drive_of(body: AdviceBody) -> tuple[cmd.Command, list[cmd.Command], int | None]:
    """The drive's command, the commands before it, and its line; 400 with the reason."""
    if (body.command is None) == (body.text is None):
        raise AdviceRefusedError("give either command (one line) or text and line")
    source = body.command if body.command is not None else body.text
    assert source is not None
    parsed = parse_any(source)
    if parsed.diagnostics:
        d = parsed.diagnostics[0]
        raise AdviceRefusedError(f"line {d.line}: {d.message}")
    steps = list(parsed.sequence.steps)
    if body.command is not None:
        if len(steps) != 1:
            raise AdviceRefusedError("command: must be one command line")
        return steps[0].command, [], None
    if body.line is None:
        raise AdviceRefusedError("line: which line of text is the drive")
    mine = [k for k, s in enumerate(steps) if s.line == body.line]
    if not mine:
        raise AdviceRefusedError(f"line {body.line}: no command on that line")
    k = mine[0]
    return steps[k].command, [s.command for s in steps[:k]], body.line


def level_map(p_m: np.ndarray) -> GroundMap:
    """A level map at the rover's reported height around it, no texture measured."""
    n = int(2 * LEVEL_MAP_HALF_M / LEVEL_MAP_CELL_M) + 1
    ground = -float(p_m[2]) - BODY_HEIGHT_M  # the body origin is that far above the ground
    return GroundMap(
        float(p_m[0]) - LEVEL_MAP_HALF_M, float(p_m[1]) - LEVEL_MAP_HALF_M, LEVEL_MAP_CELL_M,
        np.full((n, n), ground), np.full((n, n), 1.0), np.full((n, n), np.nan),
        np.full((n, n), np.nan), np.zeros((n, n), dtype=bool),
    )  # fmt: skip


def _moved(p_m: np.ndarray, yaw: float, before: list[cmd.Command]) -> tuple[np.ndarray, float]:
    """The pose after the nominal paths of the drive commands ``before``."""
    p = p_m.copy()
    for c in before:
        if isinstance(c, cmd.DriveTo):
            raise AdviceRefusedError("a DRIVE_TO before the line: its path cannot be planned")
        drive = planned(c)
        if drive is None:
            continue
        offsets, yaws = drive.step_headings(yaw)
        p[:2] += offsets[-1]
        yaw = float(yaws[-1])
    return p, yaw


def planning_surface(gmap: GroundMap) -> GroundMap:
    """The map as the advisor casts its rays on it: where no stereo measured the ground, the
    orbital DEM's heights smoothed over ``ORBITAL_SMOOTHING_M``, below which its noise (a few
    tens of cm, correlated over about a post) would be read as relief that hides the ground
    or shows it; the hills stay. Measured cells keep their own heights."""
    smooth = gaussian_filter(np.asarray(gmap.height_m, dtype=np.float64),
                             ORBITAL_SMOOTHING_M / gmap.cell_m, mode="nearest")  # fmt: skip
    return replace(gmap, height_m=np.where(gmap.imaged, gmap.height_m, smooth))


def _inside(gmap: GroundMap, p_m: np.ndarray) -> bool:
    """Whether the drive starts on the map, its planned reach (``LEVEL_MAP_HALF_M``) too."""
    i, j = gmap.cell_of(np.asarray(p_m[0]), np.asarray(p_m[1]))
    margin = LEVEL_MAP_HALF_M / gmap.cell_m
    ny, nx = gmap.shape
    return bool(margin <= i <= ny - 1 - margin and margin <= j <= nx - 1 - margin)


routes = router()


@routes.post(
    "/api/rovers/{rover}/vo-advice",
    response_model=AdviceAnswer,
    responses={**AUTH_ERRORS, **NOT_FOUND, **BAD_REQUEST, **TOO_LARGE},
)
def vo_advice(server: ServerDep, rover: RoverName, body: AdviceBody, _: Operator) -> dict[str, Any]:
    """Where the Navcams should look during a planned VO drive (module docstring)."""
    runtime = server.rover(rover)
    command, before, line = _drive_of(body)
    drive = planned(command)
    if drive is None:
        raise AdviceRefusedError(f"{command.name}: not a drive (DRIVE_STRAIGHT, DRIVE_ARC, "
                                 "TURN_IN_PLACE)")  # fmt: skip
    where = rover_site(runtime)
    with runtime.lock:
        last = runtime.last_frame
    if last is None:
        raise AdviceRefusedError("no telemetry yet: the rover's pose is not known on the ground")
    p0 = np.asarray(last["p_mission_est"], dtype=np.float64)
    q0 = np.asarray(last["q_b_ll_est"], dtype=np.float64)
    x_m = Rotation.from_quat(q0).inv().apply([1.0, 0.0, 0.0])
    p_start, yaw = _moved(p0, math.atan2(float(x_m[1]), float(x_m[0])), before)
    q_start = Rotation.from_euler("z", yaw).inv().as_quat()
    sun = sun_ll(where.start_t_s, where.lat_rad, where.lon_east_rad)
    if float(sun[2]) >= 0.0:
        raise AdviceRefusedError("the Sun is below the horizon now: no VO drive")
    feed = ground_feed(runtime, server.store)  # the pairs that came down, taken first
    feed.catch_up()
    gmap: GroundMap = planning_surface(feed.service.ground_map())
    map_text = f"the rover's ground map (orbital DEM, {feed.service.version} stereo pairs)"
    if not _inside(gmap, p_start):
        gmap, map_text = level_map(p_start), "level ground at the rover's height, no texture known"
    advice: Advice = advise(gmap, p_start, q_start, drive, sun / np.linalg.norm(sun))
    best = advice.recommended
    return {
        "line": line,
        "command": command.describe(),
        "pairs": advice.pairs,
        "recommended": None if best is None else _candidate(best),
        "arguments": None
        if best is None
        else f"vo_az_deg={best.az_deg:g} vo_el_deg={best.el_deg:g}",
        "reason": advice.reason,
        "rule": advice.rule,
        "map": map_text,
        "candidates": [_candidate(c) for c in advice.candidates],
    }
