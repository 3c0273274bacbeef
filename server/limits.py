"""Alarm limits per telemetry channel: the defaults file, its validation, and levels.

The defaults live in ``server/limits_default.json`` (its ``about`` says the format); an
operator may change a channel's levels at run time (``PUT /api/rovers/{rover}/limits/
{channel}``; stored per rover in the database, so they survive a restart). One function,
``check_levels``, validates both the file and the operator's change, so a level the file
could not hold is refused at the API too, with the same message.

Three kinds of channel:

- ``numeric``: a number; ``direction`` ``high`` alarms when the value is above a level,
  ``low`` below it; the warning level is passed first (a critical level beyond it), and
  the alarm clears once the value is back inside the warning level by ``hysteresis``
  (so a value hovering at the limit does not raise and clear on every frame).
- ``ordinal``: a name from ``values`` (worst first, like the Attitude Quality Flag);
  ``low`` alarms at or below the named level.
- ``state``: a name; alarms while it is one of the listed states.

A level may be ``null`` (or ``[]`` for a state channel): no alarm at that level.
``truth`` marks a channel scored against the simulator's truth (no real rover has it): it is
``server.channels.is_truth``'s word, not the file's, so the two cannot disagree.

Two optional keys say when a value means something (``NEEDS``: judged as no value
otherwise, so it neither raises nor clears) and whether a deliberate attitude acquisition
makes its violations expected (``shelved_while_acquiring``: not raised while a command that
sets the AQF runs, ``sequences.commands`` ``aqf_after``).

>>> limits = load_defaults()
>>> limits["aqf"].level_of("Unknown"), limits["aqf"].level_of("Coarse")
('critical', None)
>>> limits["imu_integration_s"].level_of(9000.0)
'warning'
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from server.channels import is_truth
from server.errors import InvalidError

DEFAULTS_FILE = Path(__file__).resolve().parent / "limits_default.json"
KINDS = ("numeric", "ordinal", "state")
LEVELS = ("warning", "critical")
# What a value needs to mean anything: a heading (AQF Coarse or Fine: with TiltOnly or
# Unknown the predicted HGA margin is 2 deg minus 180), or Earth above the horizon.
NEEDS: dict[str, Callable[[Mapping[str, Any]], bool]] = {
    "heading": lambda frame: frame.get("aqf") in ("Coarse", "Fine"),
    "earth_up": lambda frame: bool(frame.get("earth_up")),
}


class LimitsError(InvalidError):
    """A limit that cannot be: the message names the channel and the problem."""

    kind = "limits"


@dataclass(frozen=True)
class ChannelLimits:
    """One channel's limits (module docstring). ``warning``/``critical``: a number
    (numeric), a name (ordinal), a tuple of names (state), or ``None``."""

    channel: str
    kind: str
    warning: Any
    critical: Any
    units: str
    truth: bool
    why: str
    direction: str = "high"
    hysteresis: float = 0.0
    values: tuple[str, ...] = ()
    needs: str | None = None
    shelved_while_acquiring: bool = False

    def judged_value(self, frame: Mapping[str, Any]) -> Any:
        """The frame's value of the channel, or ``None`` where it means nothing (``needs``)."""
        if self.needs is not None and not NEEDS[self.needs](frame):
            return None
        return frame.get(self.channel)

    def level_of(self, value: Any) -> str | None:
        """``"critical"``, ``"warning"`` or ``None`` for ``value`` (``None`` for a value
        that is missing, NaN or not one of ``values``)."""
        for level in ("critical", "warning"):
            if self._beyond(value, getattr(self, level)):
                return level
        return None

    def inside(self, value: Any) -> bool:
        """Whether ``value`` is back inside the warning level by the hysteresis (an alarm
        clears); a missing value is not (nothing to judge by)."""
        if self.kind != "numeric":
            return _present(self, value) and self.level_of(value) is None
        if not _present(self, value):
            return False
        edges = [x for x in (self.warning, self.critical) if x is not None]
        if not edges:
            return True
        edge = max(edges) if self.direction == "low" else min(edges)
        h = self.hysteresis
        return bool(value >= edge + h) if self.direction == "low" else bool(value <= edge - h)

    def limit_for(self, level: str) -> Any:
        """The level's limit as JSON (a list for a state channel)."""
        limit = getattr(self, level)
        return list(limit) if isinstance(limit, tuple) else limit

    def _beyond(self, value: Any, limit: Any) -> bool:
        if limit is None or not _present(self, value):
            return False
        if self.kind == "numeric":
            return bool(value < limit) if self.direction == "low" else bool(value > limit)
        if self.kind == "state":
            return value in limit
        rank, at = self.values.index(value), self.values.index(limit)
        return rank <= at if self.direction == "low" else rank >= at

    def as_json(self) -> dict[str, Any]:
        """The channel as the API shows it."""
        out: dict[str, Any] = {
            "channel": self.channel, "kind": self.kind, "units": self.units,
            "truth": self.truth, "why": self.why,
            "warning": self.limit_for("warning"), "critical": self.limit_for("critical"),
            "needs": self.needs, "shelved_while_acquiring": self.shelved_while_acquiring,
        }  # fmt: skip
        if self.kind != "state":
            out["direction"] = self.direction
        if self.kind == "numeric":
            out["hysteresis"] = self.hysteresis
        if self.values:
            out["values"] = list(self.values)
        return out


def _present(limits: ChannelLimits, value: Any) -> bool:
    if limits.kind == "numeric":
        return _number(value)
    return isinstance(value, str) and value in limits.values


def check_levels(base: ChannelLimits, levels: dict[str, Any]) -> ChannelLimits:
    """``base`` with ``levels`` (``warning``, ``critical``, optionally ``hysteresis``)
    validated and applied; ``LimitsError`` naming the channel and the problem."""
    name = base.channel
    unknown = sorted(set(levels) - {"warning", "critical", "hysteresis"})
    if unknown:
        raise LimitsError(f"{name}: unknown field(s) {', '.join(unknown)}")
    missing = [k for k in LEVELS if k not in levels]
    if missing:
        raise LimitsError(f"{name}: {' and '.join(missing)} required (null for no level)")
    warning = _level(base, "warning", levels["warning"])
    critical = _level(base, "critical", levels["critical"])
    hysteresis = base.hysteresis
    if "hysteresis" in levels:
        if base.kind != "numeric":
            raise LimitsError(f"{name}: hysteresis is for numeric channels only")
        h = levels["hysteresis"]
        if not _number(h) or h < 0.0:
            raise LimitsError(f"{name}: hysteresis must be a finite number >= 0, got {h!r}")
        hysteresis = float(h)
    if warning is not None and critical is not None:
        _check_order(base, warning, critical)
    return replace(base, warning=warning, critical=critical, hysteresis=hysteresis)


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _level(base: ChannelLimits, level: str, value: Any) -> Any:
    name = f"{base.channel}.{level}"
    if base.kind == "state":
        if value is None:
            return ()
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise LimitsError(f"{name}: must be a list of states, got {value!r}")
        bad = [v for v in value if v not in base.values]
        if bad:
            raise LimitsError(f"{name}: unknown state(s) {', '.join(map(repr, bad))}; "
                              f"known: {', '.join(base.values)}")  # fmt: skip
        return tuple(dict.fromkeys(value))
    if value is None:
        return None
    if base.kind == "ordinal":
        if not isinstance(value, str) or value not in base.values:
            raise LimitsError(f"{name}: must be one of {', '.join(base.values)} or null, "
                              f"got {value!r}")  # fmt: skip
        return value
    if not _number(value):
        raise LimitsError(f"{name}: must be a finite number or null, got {value!r}")
    return float(value)


def _check_order(base: ChannelLimits, warning: Any, critical: Any) -> None:
    name = base.channel
    if base.kind == "state":
        both = sorted(set(warning) & set(critical))
        if both:
            raise LimitsError(f"{name}: {', '.join(both)} both warning and critical")
        return
    if base.kind == "ordinal":
        w, c = base.values.index(warning), base.values.index(critical)
    else:
        w, c = warning, critical
    if (base.direction == "low" and c > w) or (base.direction == "high" and c < w):
        side = "at or below" if base.direction == "low" else "at or above"
        raise LimitsError(
            f"{name}: critical ({critical}) must be {side} warning ({warning}) "
            f"for a {base.direction} limit"
        )


def parse_defaults(document: Any) -> dict[str, ChannelLimits]:
    """The channels of a limits document (the defaults file's JSON), validated."""
    if not isinstance(document, dict) or not isinstance(document.get("channels"), dict):
        raise LimitsError('limits: a JSON object with "channels" (an object) is required')
    extra = sorted(set(document) - {"about", "channels"})
    if extra:
        raise LimitsError(f"limits: unknown top-level key(s) {', '.join(extra)}")
    return {name: _channel(name, spec) for name, spec in document["channels"].items()}


def _channel(name: str, spec: Any) -> ChannelLimits:
    if not isinstance(spec, dict):
        raise LimitsError(f"{name}: must be an object")
    known = {"kind", "values", "direction", "warning", "critical", "hysteresis", "units",
             "why", "needs", "shelved_while_acquiring"}  # fmt: skip
    extra = sorted(set(spec) - known)
    if extra:
        raise LimitsError(f"{name}: unknown key(s) {', '.join(extra)}")
    kind = spec.get("kind")
    if kind not in KINDS:
        raise LimitsError(f"{name}.kind: one of {', '.join(KINDS)}, got {kind!r}")
    direction = spec.get("direction", "high")
    if kind != "state" and direction not in ("low", "high"):
        raise LimitsError(f"{name}.direction: low or high, got {direction!r}")
    values = spec.get("values", [])
    if kind == "numeric" and values:
        raise LimitsError(f"{name}.values: a numeric channel has none")
    if kind != "numeric" and (
        not isinstance(values, list)
        or not values
        or not all(isinstance(v, str) for v in values)
        or len(set(values)) != len(values)
    ):
        raise LimitsError(f"{name}.values: a list of distinct names is required")
    for key, kind_ok in (("units", str), ("why", str)):
        if not isinstance(spec.get(key), kind_ok):
            raise LimitsError(f"{name}.{key}: required, a {kind_ok.__name__}")
    needs = spec.get("needs")
    if needs is not None and needs not in NEEDS:
        raise LimitsError(f"{name}.needs: one of {', '.join(NEEDS)} or absent, got {needs!r}")
    shelved = spec.get("shelved_while_acquiring", False)
    if not isinstance(shelved, bool):
        raise LimitsError(f"{name}.shelved_while_acquiring: a bool, got {shelved!r}")
    base = ChannelLimits(
        channel=name, kind=kind, warning=None, critical=None, units=spec["units"],
        truth=is_truth(name), why=spec["why"], direction=direction, values=tuple(values),
        needs=needs, shelved_while_acquiring=shelved,
    )  # fmt: skip
    levels = {k: spec.get(k) for k in LEVELS}
    if "hysteresis" in spec:
        levels["hysteresis"] = spec["hysteresis"]
    return check_levels(base, levels)


def load_defaults(path: Path = DEFAULTS_FILE) -> dict[str, ChannelLimits]:
    """The defaults file's channels; ``LimitsError`` naming the file and the problem."""
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
        return parse_defaults(document)
    except (OSError, ValueError) as exc:  # LimitsError and JSONDecodeError are ValueErrors
        raise LimitsError(f"{path.name}: {exc}") from exc
