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

A value that is missing (a tilt without an accelerometer sample), or that means nothing now
(a channel's ``needs``, ``server.limits``: the true HGA figures while Earth is below the
horizon, the predicted margin without a heading) neither raises nor clears.

Beside the value that raised it (its worst), an alarm carries its latest value and that
value's time (stored when its level changes, a name changes, or at least once a minute of
the rover's clock for a number), and its active spans, raised to cleared, one per violation.

Shelved, as COSMOS and Yamcs allow: a shelved alarm is neither raised again nor escalated
(its latest value and a clear still count). An operator shelves a listed alarm for a
duration of the rover's clock (``shelve``; it is unshelved when that ends, and its shelf
goes with it once it is done). A deliberate acquisition is expected: while a command that
sets the AQF runs (its ``aqf_after`` in ``sequences.commands``), the channels whose limits
say ``shelved_while_acquiring`` are shelved, no alarm raised on them.

Every raise, escalation, re-raise, clear, shelf and acknowledgement is stored (``alarms``
table) and sent to the rover's WebSocket clients as ``{"type": "alarm", "alarm": {...}}``.
Alarms of a truth-view channel carry ``truth`` (``server.channels.is_truth``), and their
messages end with ``TRUTH_MARK``: they, their events and their notices go only to those who
may see the truth (``server.access.truth_view``).

Changing a limit (``set_limits``) re-judges that channel at once against the latest
frame: loosening a limit can clear an alarm while the rover stands still.
"""

from __future__ import annotations

import contextlib
import math
import threading
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from typing import Any

from sequences.commands import COMMANDS
from server.access.truth_view import TRUTH_MARK
from server.errors import ConflictError, DomainError, NotFoundError, UnknownChannelError
from server.limits import ChannelLimits, LimitsError, check_levels, load_defaults
from server.notices import AlarmNotice
from server.sinks import FrameBatch
from server.storage import Store
from sim.scoring.truth import merged
from sim.world.marsclock import t_s_to_utc

RANK = {"warning": 1, "critical": 2}
LATEST_EVERY_S = 60.0  # a number's latest value is stored at least this often (rover's clock)

When = Callable[[str, float], dict[str, Any]]  # (rover, t_s) -> {t_s, utc, lmst_h, sol}
Notify = Callable[[str, AlarmNotice], None]
# (rover, t_s or None for "the rover's clock now", event {text, kind, severity})
OnEvent = Callable[[str, float | None, dict[str, str]], None]


class AlarmError(DomainError):
    """An acknowledgement or a shelf that cannot be."""


class UnknownAlarmError(AlarmError, NotFoundError):
    """No alarm of that id."""


class AlarmConflictError(AlarmError, ConflictError):
    """Acknowledged already, not shelved, or done."""


def acquiring(frame: Mapping[str, Any]) -> bool:
    """Whether the frame's command deliberately sets the AQF (``aqf_after``): the frame's
    ``command`` is the command's text, its name first."""
    command = COMMANDS.get(str(frame.get("command") or "").split(" ", 1)[0])
    return command is not None and command.aqf_after is not None


def _spans(row: dict[str, Any]) -> list[list[float | None]]:
    """The active spans (a row from before they were stored: raised to its last clear)."""
    if row.get("spans"):
        return [list(span) for span in row["spans"]]
    return [[row["raised_t_s"], row["cleared_t_s"]]]


def _latest(row: dict[str, Any]) -> dict[str, Any]:
    if row.get("latest"):
        return dict(row["latest"])
    return {"value": row["value"], "t_s": row["raised_t_s"], "utc": row["raised_utc"],
            "lmst_h": row["raised_lmst_h"], "sol": row["raised_sol"]}  # fmt: skip


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
        "acknowledged": acknowledged, "cleared": cleared, "latest": _latest(row),
        "spans": [{"from_t_s": a, "to_t_s": b} for a, b in _spans(row)],
        "shelved": row.get("shelved") or None,
        "received": _received(row.get("received_t_s")),
    }  # fmt: skip


def _received(t_s: float | None) -> dict[str, Any] | None:
    """When the data that raised an alarm reached the ground (across light time)."""
    return None if t_s is None else {"t_s": t_s, "utc": t_s_to_utc(t_s).isoformat()}


def _clock(lmst_h: float) -> str:
    minutes = int(lmst_h % 24.0 * 60.0)
    return f"{minutes // 60:02d}:{minutes % 60:02d}"


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
        self._judged_t_s: dict[str, float] = {}  # rover -> the newest downlink judged
        self._received_t_s: float | None = None  # the batch being judged arrived then

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
        last_frame: Mapping[str, Any] | None,
    ) -> dict[str, Any]:  # fmt: skip
        """Validate and store an operator's levels for ``channel`` (``LimitsError`` if they
        cannot be, ``KeyError`` for an unknown channel; nothing stored then), then judge the
        channel against ``last_frame``. The channel's limits as ``limits`` lists them."""
        with self._lock:
            self._load(rover)
            if channel not in self.defaults:
                raise UnknownChannelError(
                    f"unknown channel {channel!r}; known: {', '.join(self.defaults)}"
                )
            new = check_levels(self.defaults[channel], levels)
            stored = {k: new.limit_for(k) for k in ("warning", "critical")}
            if new.kind == "numeric":
                stored["hysteresis"] = new.hysteresis
            self.store.set_limits(rover, channel, stored, by)
            self._apply(rover, channel, new)
            if last_frame is not None:
                self._judge(rover, channel, last_frame, acquiring(last_frame))
            return next(c for c in self.limits(rover) if c["channel"] == channel)

    def reset_limits(
        self, rover: str, channel: str, last_frame: Mapping[str, Any] | None
    ) -> dict[str, Any]:
        """Back to the default levels for ``channel`` (``KeyError`` if unknown)."""
        with self._lock:
            self._load(rover)
            if channel not in self.defaults:
                raise UnknownChannelError(
                    f"unknown channel {channel!r}; known: {', '.join(self.defaults)}"
                )
            self.store.reset_limits(rover, channel)
            self._apply(rover, channel, self.defaults[channel])
            if last_frame is not None:
                self._judge(rover, channel, last_frame, acquiring(last_frame))
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
        """A frame sink (``server.sinks``): judge a batch, frame by frame, every channel (a
        channel of the downlink on the downlink, a truth channel on the truth). Across light
        time the downlink is judged when it reaches the ground, and an alarm it raises
        names that arrival (``received``) beside the data's own time; data older than the
        newest already judged (a pass filling in what it sent decimated) is not judged:
        it never raises an alarm as if it were now."""
        with self._lock:
            self._load(rover)
            limits = self._limits[rover]
            any_truth = any(limits[c].truth for c in limits)
            self._received_t_s = batch.received_t_s
            newest = self._judged_t_s.get(rover, -math.inf)
            for downlink, truth in batch.pairs():
                frame: Mapping[str, Any]
                if downlink is not None and truth is not None:
                    frame = merged(downlink, truth) if any_truth else downlink
                    judged = list(limits)
                elif downlink is not None:
                    if downlink["t_s"] <= newest:
                        continue  # late fill-in (docstring)
                    frame, judged = downlink, [c for c in limits if not limits[c].truth]
                else:
                    assert truth is not None
                    frame, judged = truth, [c for c in limits if limits[c].truth]
                expected = downlink is not None and acquiring(downlink)
                for channel in judged:
                    # a truth channel on the merged frame, the rover's own on its downlink
                    seen = frame if limits[channel].truth or downlink is None else downlink
                    self._judge(rover, channel, seen, expected)
                if downlink is not None:
                    newest = max(newest, float(downlink["t_s"]))
            self._judged_t_s[rover] = newest
            self._received_t_s = None

    def _judge(self, rover: str, channel: str, frame: Mapping[str, Any], expected: bool) -> None:
        """Judge one channel on one frame; ``expected``: an attitude acquisition runs."""
        limits = self._limits[rover][channel]
        value = limits.judged_value(frame)
        level = limits.level_of(value)
        t_s = float(frame["t_s"])
        row = self._listed[rover].get(channel)
        if row is not None and row.get("shelved") and t_s >= row["shelved"]["until"]["t_s"]:
            self._change(rover, row, {"shelved": None}, t_s, what="unshelved: its shelf ended")
            row = self._listed[rover].get(channel)  # done: no longer listed
        held = expected and limits.shelved_while_acquiring
        if row is None:
            if level is not None and not held:
                self._raise(rover, limits, level, value, t_s)
            return
        held = held or bool(row.get("shelved"))
        changes: dict[str, Any] = {}
        if level is not None and not held:
            if row["cleared_t_s"] is not None:
                worse = RANK[level] > RANK[row["level"]]
                changes = {
                    "cleared_t_s": None, "cleared_utc": None, "cleared_lmst_h": None,
                    "violations": row["violations"] + 1, "spans": [*_spans(row), [t_s, None]],
                    **(self._crossing(limits, level, value) if worse else {}),
                }  # fmt: skip
            elif RANK[level] > RANK[row["level"]]:
                changes = self._crossing(limits, level, value)
        elif level is None and row["cleared_t_s"] is None and limits.inside(value):
            when = self._when(rover, t_s)
            spans = _spans(row)
            spans[-1][1] = t_s
            changes = {"cleared_t_s": t_s, "cleared_utc": when["utc"],
                       "cleared_lmst_h": when["lmst_h"], "spans": spans}  # fmt: skip
        if changes or self._latest_moved(limits, row, value, t_s):
            changes["latest"] = {"value": value, **self._when(rover, t_s)}
            self._change(rover, row, changes, t_s)

    @staticmethod
    def _latest_moved(limits: ChannelLimits, row: dict[str, Any], value: Any, t_s: float) -> bool:
        """Whether to store a listed alarm's latest value: its level changed, a name changed,
        or a number changed and the stored one is a minute (rover's clock) old."""
        latest = _latest(row)
        if value == latest["value"]:
            return False
        if limits.level_of(value) != limits.level_of(latest["value"]) or value is None:
            return True
        return limits.kind != "numeric" or t_s - latest["t_s"] >= LATEST_EVERY_S

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
            "latest": {"value": value, **when}, "spans": [[t_s, None]], "shelved": None,
            "received_t_s": self._received_t_s, **self._crossing(limits, level, value),
        }  # fmt: skip
        row["id"] = self.store.add_alarm(row)
        self._listed[rover][limits.channel] = row
        self._notify(rover, AlarmNotice(alarm_json(row)))
        self._event(rover, t_s, row, "raised")

    def _change(
        self, rover: str, row: dict[str, Any], values: dict[str, Any], t_s: float | None = None,
        what: str | None = None,
    ) -> None:  # fmt: skip
        """Store and send a change of a listed alarm (``t_s``: the frame that made it;
        ``what``: the event log's words, if not the change's own)."""
        merged = {**row, **values}
        done = merged["cleared_t_s"] is not None and merged["acknowledged_by"] is not None
        if done and merged.get("shelved"):
            values = {**values, "shelved": None}  # its shelf goes with it
        self.store.update_alarm(row["id"], values)
        row.update({k: v.isoformat() if isinstance(v, datetime) else v for k, v in values.items()})
        if done:
            self._listed[rover].pop(row["channel"], None)  # done: no longer listed
        self._notify(rover, AlarmNotice(alarm_json(row)))
        if what is not None:
            self._event(rover, t_s, row, what, cleared=True)
        elif values.get("acknowledged_by") is not None:  # then the event log's line
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
        if self._received_t_s is not None and t_s is not None:  # across light time
            data = self._when(rover, t_s)
            late_min = (self._received_t_s - t_s) / 60.0
            text += (f" (data of sol {data['sol']} {_clock(data['lmst_h'])} LMST, received "
                     f"{late_min:.0f} min later)")  # fmt: skip
        self.on_event(rover, t_s, {"text": text, "kind": "alarm", "severity": severity})

    # ---- operators ------------------------------------------------------------------

    def acknowledge(self, alarm_id: int, by: str) -> dict[str, Any]:
        """Acknowledge an alarm (``AlarmError`` 404 unknown, 409 acknowledged already)."""
        with self._lock:
            found = self.store.alarms(alarm_id=alarm_id)
            if not found:
                raise UnknownAlarmError(f"no alarm {alarm_id}")
            rover = found[0]["rover"]
            self._load(rover)
            listed = self._listed[rover].get(found[0]["channel"])
            row = listed if listed is not None and listed["id"] == alarm_id else found[0]
            if row["acknowledged_by"] is not None:
                by_at = f"{row['acknowledged_by']} at {row['acknowledged_at']}"
                raise AlarmConflictError(f"alarm {alarm_id} was acknowledged by {by_at}")
            self._change(rover, row, {"acknowledged_by": by, "acknowledged_at": datetime.now(UTC)})
            return alarm_json(row)

    def shelve(
        self, alarm_id: int, duration_s: float, by: str, reason: str, now_t_s: float | None
    ) -> dict[str, Any]:
        """Shelve a listed alarm for ``duration_s`` of the rover's clock from ``now_t_s``
        (its latest value's time if ``None``); ``AlarmError`` 404 unknown, 409 done."""
        with self._lock:
            row = self._listed_row(alarm_id, "shelve")
            start = _latest(row)["t_s"] if now_t_s is None else now_t_s
            until = self._when(row["rover"], start + duration_s)
            shelf = {"by": by, "reason": reason, "until": until}
            lmst = f"sol {until['sol']} {until['lmst_h'] % 24:.2f} h LMST"
            self._change(row["rover"], row, {"shelved": shelf}, None,
                         what=f"shelved by {by} until {lmst}")  # fmt: skip
            return alarm_json(row)

    def unshelve(self, alarm_id: int, by: str) -> dict[str, Any]:
        """End a shelf before its time (``AlarmError`` 404 unknown, 409 not shelved)."""
        with self._lock:
            row = self._listed_row(alarm_id, "unshelve")
            if not row.get("shelved"):
                raise AlarmConflictError(f"alarm {alarm_id} is not shelved")
            self._change(row["rover"], row, {"shelved": None}, None, what=f"unshelved by {by}")
            return alarm_json(row)

    def _listed_row(self, alarm_id: int, verb: str) -> dict[str, Any]:
        found = self.store.alarms(alarm_id=alarm_id)
        if not found:
            raise UnknownAlarmError(f"no alarm {alarm_id}")
        rover = found[0]["rover"]
        self._load(rover)
        listed = self._listed[rover].get(found[0]["channel"])
        if listed is None or listed["id"] != alarm_id:
            raise AlarmConflictError(f"alarm {alarm_id} is done (acknowledged and cleared): "
                                  f"nothing to {verb}")  # fmt: skip
        return listed

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
