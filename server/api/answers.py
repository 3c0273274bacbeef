"""What the routes answer: one pydantic model per answer, so that ``/docs`` shows each.

The models describe the JSON the routes have always sent, field for field (the console in
``web/`` and the tests read it). Each is an ``Answer``: it keeps a key it does not declare
(``extra="allow"``), so a field added to a record upstream reaches the client before it is
described here; a route's answer is dumped without the fields its dict did not set
(``server.api.routing.AuthFirstRoute``), so a frame outside the truth view carries no truth
key, not a null one. ``Frame`` is built from the two records' dataclasses (``Downlink`` and
``Truth``), the one definition of their fields.
"""

from __future__ import annotations

import typing
from dataclasses import fields
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Discriminator, Field, Tag, create_model
from pydantic.fields import FieldInfo

from sim.loop.downlink import Downlink
from sim.scoring.truth import Truth


class Answer(BaseModel):
    """A route's answer (module docstring)."""

    model_config = ConfigDict(extra="allow")


def _frame_model(name: str = "Frame", truth: bool = True) -> type[Answer]:
    """A frame: the downlink record's fields, then the truth record's (present in the truth
    view only); each may be null (a figure that does not exist)."""
    declared: dict[str, Any] = {}
    for record, where in ((Downlink, "downlink"), (Truth, "truth"))[: 2 if truth else 1]:
        hints = typing.get_type_hints(record)
        extras = typing.get_type_hints(record, include_extras=True)
        for f in fields(record):
            if f.name in declared:
                continue
            about = [m for m in getattr(extras[f.name], "__metadata__", ()) if
                     isinstance(m, FieldInfo)]  # fmt: skip
            text = about[0].description if about else None
            declared[f.name] = (
                hints[f.name] | None,
                Field(default=None, description=f"{text} ({where} record)" if text else where),
            )
    model: type[Answer] = create_model(
        name, __base__=Answer, __doc__="A telemetry frame: the downlink record, merged with "
        "its truth record in the truth view (GET /api/schema/downlink and /truth).",
        **declared,
    )  # fmt: skip
    return model


Frame = _frame_model()


class When(Answer):
    """A moment of a rover's clock: TT seconds, UTC and LMST (and the sol, where given)."""

    t_s: float
    utc: str
    lmst_h: float
    sol: int | None = None


class Received(Answer):
    """When data reached the ground (TT seconds and UTC)."""

    t_s: float
    utc: str


class Clock(Answer):
    """A rover's clock: running or paused, and its speed factor ("max": as fast as it can)."""

    running: bool
    speed: float | Literal["max"]


class QueuedSummary(Answer):
    """A queued sequence as a rover's state lists it."""

    sequence_id: int
    name: str | None
    next_step: int
    steps: int


class RoverSummary(Answer):
    """A rover and its clock (``GET /api/rovers``)."""

    rover: str
    site: str
    mission: str
    t_s: float
    utc: str
    sol: int
    lmst_h: float
    clock: Clock
    effective_speed: float | Literal["max"]
    executing: str | None
    queue: list[QueuedSummary]


class RoverState(RoverSummary):
    """A rover's state: its summary, its latest frame and whether it carries the truth."""

    frame: Frame | None  # type: ignore[valid-type]
    truth: bool


class ArgumentSpec(Answer):
    """One argument of a command (``sequences.commands.ArgSpec``)."""

    name: str
    type: str
    unit: str | None
    min: float | None
    max: float | None
    min_exclusive: bool
    range: str | None
    default: Any = Field(description="the default value, null when none")
    required: bool
    note: str | None


class CommandSpec(Answer):
    """A command of the dictionary with its arguments."""

    command: str
    doc: str
    args: list[ArgumentSpec]


class Diagnostic(Answer):
    """One problem in a sequence (``sequences.language.Diagnostic``)."""

    line: int
    column: int
    code: str
    message: str


class Queued(Answer):
    """An immediate command, queued (``POST .../commands``)."""

    id: int
    status: Literal["queued"]
    errors: list[Diagnostic]
    warnings: list[Diagnostic]


class RecordSchema(Answer):
    """A JSON schema (draft 2020-12) of a record: its fields with their types and units."""

    title: str
    type: Literal["object"]
    properties: dict[str, dict[str, Any]]
    required: list[str] = []


class StoredSequence(Answer):
    """A sequence as stored (``GET /api/rovers/{rover}/sequences`` lists these)."""

    id: int
    rover: str
    name: str
    format: str
    status: str
    detail: str | None
    errors: list[Diagnostic]
    warnings: list[Diagnostic]
    created_at: str
    updated_at: str
    submitted_by: str | None


class StoredStep(Answer):
    """A stored step of a sequence."""

    line: int
    command: str
    args: dict[str, Any]
    time: str


class SequenceRecord(StoredSequence):
    """One sequence with its source and steps (``GET /api/sequences/{id}``)."""

    source: str
    steps: list[StoredStep]


class CancelledSequence(Answer):
    """A cancelled sequence, and where it stopped; across light time, for a sequence already
    radiated, a cancel sent (``cancel-sent``: it goes up, and the rover reports)."""

    id: int
    status: Literal["cancelled", "cancel-sent"]
    detail: str


class QueueStep(Answer):
    """A step of a queued or recent sequence, with its status and times."""

    index: int
    line: int | None
    command: str
    tag: str
    status: str
    reason: str | None
    start: When | None
    end: When | None


class QueueEntry(Answer):
    """A queued sequence: its place, whether it may move, and its steps."""

    position: int
    sequence_id: int
    name: str | None
    immediate: bool
    status: Literal["queued", "running", "waiting", "radiated"]
    movable: bool
    pinned: str | None
    submitted_by: str | None
    next_step: int
    step_count: int
    steps: list[QueueStep]
    side: Literal["ground", "onboard"] | None = None  # across light time: which side
    stages: list[dict[str, Any]] = []  # its command history: stage, t_s, detail, when


class RecentSequence(Answer):
    """A sequence that left the queue (completed, failed or cancelled)."""

    sequence_id: int
    name: str | None
    status: str
    detail: str | None
    submitted_by: str | None
    step_count: int
    steps: list[QueueStep]


class Queue(Answer):
    """A rover's queue (``recent`` only in ``GET .../queue``)."""

    rover: str
    queue: list[QueueEntry]
    recent: list[RecentSequence] | None = None


class LoggedEvent(Answer):
    """An event of the log, at its moment (``estimation.events`` kinds and severities)."""

    t_s: float
    utc: str | None = None
    lmst_h: float
    sol: int
    text: str
    kind: str
    severity: str


class EventPage(Answer):
    """A page of the event log, newest first."""

    rover: str
    kinds: list[str]
    offset: int
    limit: int
    total: int
    events: list[LoggedEvent]


class ChannelInfo(Answer):
    """A numeric telemetry channel."""

    name: str
    unit: str
    truth: bool


class ChannelSeries(Answer):
    """One channel over sols, decimated (null: no value)."""

    rover: str
    sol_from: int
    sol_to: int
    frames: int
    decimated: bool
    t_s: list[float]
    sol: list[int]
    lmst_h: list[float]
    values: list[Any]


class Scene(Answer):
    """The 3D view of a rover on this origin."""

    url: str
    frames_drawn: int
    truth: bool


class Identity(Answer):
    """Who a request acts as, and what this server shows it."""

    name: str
    role: str | None
    public_read: bool
    roles: list[str]
    truth_view: str
    sees_truth: bool


class SignedOut(Answer):
    signed_out: bool


class User(Answer):
    """A user, its role, creation time and live tokens."""

    name: str
    role: str
    created_at: str
    live_tokens: int


class IssuedToken(Answer):
    """A token, shown in this answer only."""

    name: str
    role: str
    token: str
    expires_at: str


class RoleChanged(Answer):
    name: str
    role: str


class TokensRevoked(Answer):
    name: str
    revoked: int


class AuditRow(Answer):
    """One audited request (``server.access.audit``)."""

    id: int
    at: str
    rover: str | None
    rover_clock: str | None
    username: str
    role: str | None
    method: str
    path: str
    action: str | None
    status: int
    result: str
    detail: str | None


class CommandRun(Answer):
    """A command as it ran (the timeline's commands, the ``command`` notice's)."""

    sequence_id: int | None
    command: str
    status: str
    submitted_by: str | None
    start: When
    end: When


class Interval(Answer):
    """A span over which a frame field (NATE's mode, the AQF) kept one value."""

    value: Any
    start: When
    end: When | None = None


class SolSummary(Answer):
    """A sol at a glance, from the downlink (the estimated distance)."""

    frames: int
    commands: int
    commands_failed: int
    distance_m: float
    max_imu_integration_s: float | None


class SolTruth(Answer):
    """A sol's truth and its scores (the truth view's)."""

    distance_m: float
    max_position_error_m: float | None
    max_attitude_error_deg: float | None
    min_hga_margin_deg: float | None
    events: list[LoggedEvent]


class LimitLevels(Answer):
    """A channel's levels (numbers, a level's name, a list of states, or null)."""

    warning: Any
    critical: Any


class Limits(LimitLevels):
    """A channel's alarm limits (``server.limits``)."""

    channel: str
    kind: str
    units: str | None
    truth: bool
    why: str | None
    needs: Any = None
    shelved_while_acquiring: bool | None = None
    direction: str | None = None
    values: list[str] | None = None
    hysteresis: float | None = None
    default: LimitLevels
    edited_by: str | None
    edited_at: str | None


class Acknowledged(Answer):
    by: str
    at_utc: str


class Shelf(Answer):
    """An alarm's shelf: until when of the rover's clock, by whom and why."""

    by: str
    reason: str
    until: When


class Span(Answer):
    """A span over which the alarm's channel was out of its limit (open: ``to_t_s`` null)."""

    from_t_s: float
    to_t_s: float | None


class Alarm(Answer):
    """An alarm (``server.alarms``): raised, its latest value, acknowledged, cleared."""

    id: int
    rover: str
    channel: str
    level: str
    truth: bool
    value: Any
    limit: Any
    units: str | None
    message: str
    violations: int
    raised: When
    acknowledged: Acknowledged | None
    cleared: When | None
    latest: When | None = None
    spans: list[Span] = []
    shelved: Shelf | None = None
    received: Received | None = Field(
        default=None, description="across light time: when the data that raised it came down"
    )


class FaultEntry(Answer):
    """A fault the conductor injected (``server.faults``): its id, kind and parameters (units
    in their names), in words, when it is due (``at``) and was applied (``applied``; null
    while pending), its ``state`` (pending, applied, or failed: ``error`` says why) and
    whether it is ``revealed`` to every reader."""

    fault_id: int
    kind: str
    parameters: dict[str, str | float]
    description: str
    at: When
    applied: When | None
    state: Literal["pending", "applied", "failed"]
    error: str | None
    revealed: bool


class Faults(Answer):
    """A rover's faults in the order injected (the conductor's list); after a reveal,
    ``revealed`` says how many the reveal made visible."""

    rover: str
    faults: list[FaultEntry]
    revealed: int | None = None


class Timeline(Answer):
    """One sol: commands, NATE mode and AQF intervals, events, alarms, distance, summary,
    and in the truth view its ``truth`` part."""

    rover: str
    sol: int
    start: When
    end: When
    commands: list[CommandRun]
    nate_modes: list[Interval]
    aqf: list[Interval]
    events: list[LoggedEvent]
    alarms: list[Alarm]
    distance_m: float
    summary: SolSummary
    faults: list[FaultEntry] = Field(
        default_factory=list,
        description="the faults applied in the sol: all in the truth view, else the revealed",
    )
    truth: SolTruth | None = None


class LiveEvent(Answer):
    """An event as the WebSocket carries it: stamped with its own frame's time."""

    text: str
    kind: str
    severity: str
    t_s: float | None
    sol: int | None
    lmst_h: float | None


class FrameMessage(_frame_model("DownlinkFrame", truth=False)):  # type: ignore[misc]
    """A frame on the WebSocket (it has no ``type``): the newest frame played out, with the
    events of every frame since the last message and what this client lost. The truth
    record's fields, merged in for the truth view, are in ``GET /api/schema/truth``."""

    published_wall: float
    events: list[LiveEvent]
    dropped: int
    dropped_events: int
    received_t_s: float | None = Field(
        default=None, description="across light time: when this downlink reached the ground"
    )
    truth_t_s: float | None = Field(
        default=None, description="across light time, the truth view: the truth's own (live) time"
    )


class _NoticeMessage(Answer):
    dropped_notices: int


class AlarmMessage(_NoticeMessage):
    type: Literal["alarm"]
    alarm: Alarm


class CommandMessage(_NoticeMessage):
    type: Literal["command"]
    command: CommandRun


class EventMessage(_NoticeMessage):
    type: Literal["event"]
    event: LiveEvent


class QueueMessage(_NoticeMessage):
    type: Literal["queue"]
    rover: str
    queue: list[QueueEntry]


def _message_tag(message: Any) -> str:
    """A message's tag: its ``type``, or ``frame`` for a frame (which has none)."""
    got = message.get("type") if isinstance(message, dict) else getattr(message, "type", None)
    return str(got) if got is not None else "frame"


WsMessage = Annotated[
    Annotated[FrameMessage, Tag("frame")]
    | Annotated[AlarmMessage, Tag("alarm")]
    | Annotated[CommandMessage, Tag("command")]
    | Annotated[EventMessage, Tag("event")]
    | Annotated[QueueMessage, Tag("queue")],
    Discriminator(_message_tag),
]
"""A message of ``/ws/rovers/{rover}/telemetry``: a frame, or a notice tagged by ``type``."""


class UnionSchema(Answer):
    """A JSON schema (draft 2020-12) of a tagged union: its members in ``oneOf``, their
    definitions in ``$defs``."""

    one_of: list[dict[str, Any]] = Field(alias="oneOf")
    defs: dict[str, dict[str, Any]] = Field(alias="$defs")
