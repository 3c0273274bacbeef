"""The alarm engine: each played-out frame batch judged against the rover's limits.

As in Yamcs, a channel has at most one alarm *listed* at a time, and an alarm stays listed
until it is both acknowledged (by an operator: who and when) and cleared (the value back
inside its limits): so the operator sees every alarm, even one whose value came back
before anyone looked. While it is listed:

- a value beyond the critical level escalates a warning to critical (never back down:
  the alarm keeps its worst level, its value and the limit crossed);
- the value clears it only once back inside the warning level by the channel's
  hysteresis (``server.limits``), so a value hovering at a limit raises one alarm, not
  one a frame;
- a new violation after it cleared (and before it was acknowledged) raises it again: the
  clear time is dropped and ``violations`` counts, rather than a new alarm.

A value that is missing (a tilt without an accelerometer sample, HGA figures while Earth is
below the horizon) neither raises nor clears. Every raise, escalation, re-raise, clear and
acknowledgement is stored (``alarms`` table) and sent to the rover's WebSocket clients as
``{"type": "alarm", "alarm": {...}}``. Alarms of a truth-view channel carry ``truth``, and
their messages end with ``TRUTH_MARK``: they, their events and their notices go only to
those who may see the truth (``server.access.truth_view``).

Changing a limit (``set_limits``) re-judges that channel at once against the latest
frame: loosening a limit can clear an alarm while the rover stands still.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable
from datetime import UTC, datetime
from typing import Any

from server.access.truth_view import TRUTH_MARK
from server.limits import ChannelLimits, LimitsError, check_levels, load_defaults
from server.sinks import FrameBatch
from server.storage import Store
from sim.scoring.truth import merged

# Channels that mean nothing while Earth is below the horizon (sim.loop.session's HGA figures).
EARTH_CHANNELS = ("hga_margin_deg", "hga_error_deg")
RANK = {"warning": 1, "critical": 2}

When = Callable[[str, float], dict[str, Any]]  # (rover, t_s) -> {t_s, utc, lmst_h, sol}
Notify = Callable[[str, dict[str, Any]], None]
# (rover, t_s or None for "the rover's clock now", event {text, kind, severity})
OnEvent = Callable[[str, float | None, dict[str, str]], None]


class AlarmError(Exception):
    """An acknowledgement that cannot be (``status`` 404 or 409)."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


def alarm_json(row: dict[str, Any]) -> dict[str, Any]:
    """A stored alarm row as the API, the WebSocket and the timeline show it."""
    cleared = None
    if row["cleared_t_s"] is not None:
        cleared = {"t_s": row["cleared_t_s"], "utc": row["cleared_utc"],
                   "lmst_h": row["cleared_lmst_h"]}  # fmt: skip
    acknowledged = None
    if row["acknowledged_by"] is not None:
        acknowledged = {"by": row["acknowledged_by"], "at_utc": row["acknowledged_at"]}
    return {
        "id": row["id"], "rover": row["rover"], "channel": row["channel"],
        "level": row["level"], "truth": bool(row["truth"]), "value": row["value"],
        "limit": row["limit_value"], "units": row["units"], "message": row["message"],
        "violations": row["violations"],
        "raised": {"t_s": row["raised_t_s"], "utc": row["raised_utc"],
                   "lmst_h": row["raised_lmst_h"], "sol": row["raised_sol"]},
        "acknowledged": acknowledged, "cleared": cleared,
    }  # fmt: skip


def _message(limits: ChannelLimits, level: str, value: Any) -> str:
    limit = limits.limit_for(level)
    units = f" {limits.units}" if limits.units else ""
    shown = f"{value:.4g}{units}" if isinstance(value, float) else f"{value}{units}"
    if limits.kind == "state":
        text = f"{limits.channel} {shown}: a {level} state"
    elif limits.kind == "ordinal":
        side = "at or below" if limits.direction == "low" else "at or above"
        text = f"{limits.channel} {shown}, {side} the {level} level {limit}"
    else:
        side = "below" if limits.direction == "low" else "above"
        text = f"{limits.channel} {shown}, {side} the {level} limit {limit:g}{units}"
    return text + (TRUTH_MARK if limits.truth else "")


class AlarmEngine:
    """Limits and listed alarms of every rover (module docstring). ``when`` gives a time's
    ``{t_s, utc, lmst_h, sol}`` for a rover; ``notify`` sends a WebSocket notice;
    ``on_event`` (if set) hears each raise, escalation, clear and acknowledgement as an
    event of kind ``alarm`` for the event log."""

    def __init__(self, store: Store, when: When, notify: Notify) -> None:
        self.on_event: OnEvent | None = None
        self.store = store
        self.defaults = load_defaults()
        self._when = when
        self._notify = notify
        self._lock = threading.RLock()
        self._limits: dict[str, dict[str, ChannelLimits]] = {}
        self._listed: dict[str, dict[str, dict[str, Any]]] = {}  # rover -> channel -> row
        self._edited: dict[str, dict[str, dict[str, Any]]] = {}  # operators' levels

    # ---- limits ---------------------------------------------------------------------

    def limits(self, rover: str) -> list[dict[str, Any]]:
        """Every channel's limits for ``rover``, with the default and who changed it."""
        with self._lock:
            self._load(rover)
            out = []
            for name, limits in self._limits[rover].items():
                default = self.defaults[name]
                edited = self._edited[rover].get(name)
                out.append({
                    **limits.as_json(),
                    "default": {k: v for k, v in default.as_json().items()
                                if k in ("warning", "critical", "hysteresis")},
                    "edited_by": edited["updated_by"] if edited else None,
                    "edited_at": edited["updated_at"] if edited else None,
                })  # fmt: skip
            return out

    def set_limits(
        self, rover: str, channel: str, levels: dict[str, Any], by: str,
        last_frame: dict[str, Any] | None,
    ) -> dict[str, Any]:  # fmt: skip
        """Validate and store an operator's levels for ``channel`` (``LimitsError`` if they
        cannot be, ``KeyError`` for an unknown channel; nothing stored then), then judge the
        channel against ``last_frame``. The channel's limits as ``limits`` lists them."""
        with self._lock:
            self._load(rover)
            if channel not in self.defaults:
                raise KeyError(f"unknown channel {channel!r}; known: {', '.join(self.defaults)}")
            new = check_levels(self.defaults[channel], levels)
            stored = {k: new.limit_for(k) for k in ("warning", "critical")}
            if new.kind == "numeric":
                stored["hysteresis"] = new.hysteresis
            self.store.set_limits(rover, channel, stored, by)
            self._apply(rover, channel, new)
            if last_frame is not None:
                self._judge(rover, channel, last_frame)
            return next(c for c in self.limits(rover) if c["channel"] == channel)

    def reset_limits(
        self, rover: str, channel: str, last_frame: dict[str, Any] | None
    ) -> dict[str, Any]:
        """Back to the default levels for ``channel`` (``KeyError`` if unknown)."""
        with self._lock:
            self._load(rover)
            if channel not in self.defaults:
                raise KeyError(f"unknown channel {channel!r}; known: {', '.join(self.defaults)}")
            self.store.reset_limits(rover, channel)
            self._apply(rover, channel, self.defaults[channel])
            if last_frame is not None:
                self._judge(rover, channel, last_frame)
            return next(c for c in self.limits(rover) if c["channel"] == channel)

    def _apply(self, rover: str, channel: str, limits: ChannelLimits) -> None:
        self._limits[rover][channel] = limits
        self._edited[rover] = self.store.stored_limits(rover)

    def _load(self, rover: str) -> None:
        """The rover's limits (defaults overlaid with the stored ones) and listed alarms,
        from storage the first time (after a restart: as they were)."""
        if rover in self._limits:
            return
        edited = self.store.stored_limits(rover)
        limits = dict(self.defaults)
        for name, row in edited.items():
            if name not in limits:
                continue  # a channel this version no longer has
            # stored by a version with other rules: the default applies
            with contextlib.suppress(LimitsError):
                limits[name] = check_levels(limits[name], row["levels"])
        self._limits[rover] = limits
        self._edited[rover] = edited
        listed = self.store.alarms(rover, listed=True)
        self._listed[rover] = {}
        for row in reversed(listed):  # oldest first: the newest of a channel wins
            self._listed[rover][row["channel"]] = row

    # ---- judging frames -------------------------------------------------------------

    def publish(self, rover: str, batch: FrameBatch) -> None:
        """A frame sink (``server.sinks``): judge a played-out batch, frame by frame, every
        channel (a channel of the downlink on the downlink, a truth channel on the truth)."""
        frames = [merged(d, t) for d, t in zip(batch.downlink, batch.truth, strict=True)]
        with self._lock:
            self._load(rover)
            for frame in frames:
                for channel in self._limits[rover]:
                    self._judge(rover, channel, frame)

    def _judge(self, rover: str, channel: str, frame: dict[str, Any]) -> None:
        limits = self._limits[rover][channel]
        value = frame.get(channel)
        if channel in EARTH_CHANNELS and not frame.get("earth_up"):
            value = None
        level = limits.level_of(value)
        row = self._listed[rover].get(channel)
        t_s = float(frame["t_s"])
        if level is not None:
            if row is None:
                self._raise(rover, limits, level, value, t_s)
            elif row["cleared_t_s"] is not None:
                worse = RANK[level] > RANK[row["level"]]
                self._change(rover, row, {
                    "cleared_t_s": None, "cleared_utc": None, "cleared_lmst_h": None,
                    "violations": row["violations"] + 1,
                    **(self._crossing(limits, level, value) if worse else {}),
                }, t_s)  # fmt: skip
            elif RANK[level] > RANK[row["level"]]:
                self._change(rover, row, self._crossing(limits, level, value), t_s)
        elif row is not None and row["cleared_t_s"] is None and limits.inside(value):
            when = self._when(rover, t_s)
            self._change(rover, row, {"cleared_t_s": t_s, "cleared_utc": when["utc"],
                                      "cleared_lmst_h": when["lmst_h"]})  # fmt: skip

    @staticmethod
    def _crossing(limits: ChannelLimits, level: str, value: Any) -> dict[str, Any]:
        return {"level": level, "value": value, "limit_value": limits.limit_for(level),
                "message": _message(limits, level, value)}  # fmt: skip

    def _raise(self, rover: str, limits: ChannelLimits, level: str, value: Any, t_s: float) -> None:
        when = self._when(rover, t_s)
        row: dict[str, Any] = {
            "rover": rover, "channel": limits.channel, "truth": limits.truth,
            "units": limits.units, "violations": 1, "raised_t_s": t_s,
            "raised_utc": when["utc"], "raised_lmst_h": when["lmst_h"],
            "raised_sol": when["sol"], "cleared_t_s": None, "cleared_utc": None,
            "cleared_lmst_h": None, "acknowledged_by": None, "acknowledged_at": None,
            **self._crossing(limits, level, value),
        }  # fmt: skip
        row["id"] = self.store.add_alarm(row)
        self._listed[rover][limits.channel] = row
        self._notify(rover, {"type": "alarm", "alarm": alarm_json(row)})
        self._event(rover, t_s, row, "raised")

    def _change(
        self, rover: str, row: dict[str, Any], values: dict[str, Any], t_s: float | None = None
    ) -> None:
        """Store and send a change of a listed alarm (``t_s``: the frame that made it)."""
        self.store.update_alarm(row["id"], values)
        row.update({k: v.isoformat() if isinstance(v, datetime) else v for k, v in values.items()})
        if row["cleared_t_s"] is not None and row["acknowledged_by"] is not None:
            self._listed[rover].pop(row["channel"], None)  # done: no longer listed
        self._notify(rover, {"type": "alarm", "alarm": alarm_json(row)})
        if values.get("acknowledged_by") is not None:  # then the event log's line
            self._event(rover, None, row, f"acknowledged by {values['acknowledged_by']}")
        elif values.get("cleared_t_s") is not None:
            self._event(rover, values["cleared_t_s"], row, "cleared", cleared=True)
        elif "violations" in values:
            self._event(rover, t_s, row, "raised again")
        elif "level" in values:
            self._event(rover, t_s, row, "escalated")

    def _event(
        self, rover: str, t_s: float | None, row: dict[str, Any], what: str, cleared: bool = False
    ) -> None:
        if self.on_event is None:
            return
        severity = "info" if cleared or what.startswith("acknowledged") else (
            "error" if row["level"] == "critical" else "warning")  # fmt: skip
        text = f"alarm {what}: {row['message']}"  # the message names the channel, truth view
        self.on_event(rover, t_s, {"text": text, "kind": "alarm", "severity": severity})

    # ---- operators ------------------------------------------------------------------

    def acknowledge(self, alarm_id: int, by: str) -> dict[str, Any]:
        """Acknowledge an alarm (``AlarmError`` 404 unknown, 409 acknowledged already)."""
        with self._lock:
            found = self.store.alarms(alarm_id=alarm_id)
            if not found:
                raise AlarmError(404, f"no alarm {alarm_id}")
            rover = found[0]["rover"]
            self._load(rover)
            listed = self._listed[rover].get(found[0]["channel"])
            row = listed if listed is not None and listed["id"] == alarm_id else found[0]
            if row["acknowledged_by"] is not None:
                by_at = f"{row['acknowledged_by']} at {row['acknowledged_at']}"
                raise AlarmError(409, f"alarm {alarm_id} was acknowledged by {by_at}")
            self._change(rover, row, {"acknowledged_by": by, "acknowledged_at": datetime.now(UTC)})
            return alarm_json(row)

    def listed(
        self, rover: str, listed: bool | None, limit: int, truth: bool = True
    ) -> list[dict[str, Any]]:
        """A rover's alarms, newest first (``listed`` as ``Store.alarms``); those of truth
        channels only if ``truth`` (the truth view: ``server.access.truth_view``)."""
        rows = self.store.alarms(rover, listed=listed, limit=limit if truth else None)
        return [alarm_json(r) for r in rows if truth or not r["truth"]][:limit]

    def truth_alarm(self, alarm_id: int) -> bool:
        """Whether alarm ``alarm_id`` is on a truth channel (False for no such alarm)."""
        found = self.store.alarms(alarm_id=alarm_id)
        return bool(found and found[0]["truth"])
