"""The comm routes' answers (``server.comm.api``): a rover's link as the ground sees it."""

from __future__ import annotations

from typing import Literal

from server.api.answers import Answer


class Moment(Answer):
    """A moment: TT seconds, UTC, the rover's sol and LMST."""

    t_s: float
    utc: str
    sol: int
    lmst_h: float


class CommWindow(Answer):
    """An uplink window, a relay pass or a direct-to-Earth session; a past pass with what
    the ground received of it (null: nothing yet, or not a pass)."""

    kind: Literal["uplink", "relay", "dte"]
    start_t_s: float
    end_t_s: float
    minutes: float
    rate_bps: float
    peak_elev_deg: float
    capacity_mbit: float
    start: Moment
    end: Moment
    received_mbit: float | None
    received_products: int | None


class UplinkEntry(Answer):
    """Something the ground radiates: waiting for its window, or radiated (on its way or
    onboard)."""

    uplink_id: int
    kind: Literal["sequence", "cancel"]
    sequence_id: int
    bits: int
    accepted_t_s: float
    radiated_t_s: float | None
    arrival_t_s: float | None


class StoreReport(Answer):
    """The onboard store as the rover reported it at the opening of a pass."""

    used_bits: int
    capacity_bits: int
    held: int
    dropped: int
    fill_pct: float
    reported: Moment
    received: Moment


class Gap(Answer):
    """Products the store dropped (full), as the rover reported them."""

    priority: int
    kind: str
    first_t_s: float
    last_t_s: float
    count: int
    bits: int
    received_t_s: float


class NewestData(Answer):
    """The newest downlink on the ground: its own time, when it came down, how old."""

    data: Moment
    received: Moment | None
    age_s: float
    received_ago_s: float | None


class CommState(Answer):
    """``GET /api/rovers/{rover}/comm``: the link as the ground knows it."""

    rover: str
    mode: Literal["instant", "mission"]
    plan: dict[str, float]
    now: Moment
    one_way_light_time_s: float
    next_uplink: CommWindow | None
    next_pass: CommWindow | None
    windows: list[CommWindow]
    store: StoreReport | None
    uplinks: list[UplinkEntry]
    gaps: list[Gap]
    newest_data: NewestData | None
