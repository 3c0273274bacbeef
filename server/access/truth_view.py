"""Who may see the simulator's truth: the one place that decides it (docs/DESIGN.md, "Two
records").

A real ground system only has what the rover sends (``sim.loop.downlink.Downlink``). The
simulator also knows the truth and scores the rover against it (``sim.scoring.truth.Truth``):
the test conductor's view. ``roverops serve --truth-view`` says who gets it:

- ``everyone`` (the default): every reader, so someone learning alone on ``make run`` sees
  how good the estimate is;
- ``conductor``: only the ``conductor`` role and above; a viewer or an operator gets the
  downlink alone, everywhere (REST, CSV, channels, timelines, alarms, events, both
  WebSockets and the 3D view), as a trainee in front of a real rover would.

``may_see_truth`` answers for one caller; the routes ask it through
``server.api.deps.SeesTruth``, the WebSocket hub and the 3D view at their handshake. The
helpers below take the truth out of what a caller who may not see it is sent.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Literal

from fastapi import HTTPException

from server.access.accounts import Principal
from server.channels import SIDE_TRUTH, truth_channel_names
from sim.scoring.truth import TRUTH_FIELDS

TruthView = Literal["everyone", "conductor"]
TRUTH_VIEWS: tuple[TruthView, ...] = ("everyone", "conductor")
TRUTH_ROLE = "conductor"  # the lowest role that sees the truth under --truth-view conductor
# The end of an alarm's message on a truth channel (server.alarms), so of its events too.
TRUTH_MARK = " (truth view)"
# The truth record's figures (its time is the downlink's; its events and side estimators'
# errors are merged into the downlink's lists, not fields of their own).
TRUTH_FIGURES = frozenset(TRUTH_FIELDS) - {"t_s", "events", "estimators"}


def check_truth_view(value: str) -> TruthView:
    """``value`` as a truth view; ``ValueError`` naming the parameter otherwise."""
    for known in TRUTH_VIEWS:
        if value == known:
            return known
    raise ValueError(f"truth_view must be one of {', '.join(TRUTH_VIEWS)}, got {value!r}")


def may_see_truth(truth_view: str, principal: Principal) -> bool:
    """True when ``principal`` may see the truth on a server whose truth view is
    ``truth_view`` (an anonymous reader only when everyone may)."""
    return truth_view == "everyone" or principal.may(TRUTH_ROLE)


def truth_refused(what: str) -> HTTPException:
    """The 403 for a truth figure asked for by one who may not see it."""
    return HTTPException(
        403,
        f"{what} is the simulator's truth: this server shows it to the {TRUTH_ROLE} role "
        "and above (the truth view, roverops serve --truth-view)",
    )


def is_truth_channel(channel: str) -> bool:
    """A channel of the truth record (``server.channels``), or a side estimator's error."""
    return channel in truth_channel_names()


def ground_frame(frame: dict[str, Any] | None) -> dict[str, Any] | None:
    """A merged frame without its truth: the truth record's fields and the side estimators'
    errors removed (for an answer built from merged frames)."""
    if frame is None:
        return None
    out = {k: v for k, v in frame.items() if k not in TRUTH_FIGURES}
    if "estimators" in frame:
        out["estimators"] = {
            name: {k: v for k, v in side.items() if k not in SIDE_TRUTH}
            for name, side in (frame["estimators"] or {}).items()
        }
    return out


def is_truth_event(event: dict[str, Any]) -> bool:
    """An event that tells the truth: one of an alarm on a truth channel."""
    return event.get("kind") == "alarm" and str(event.get("text", "")).endswith(TRUTH_MARK)


def ground_events(events: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """``events`` without those that tell the truth."""
    return [e for e in events if not is_truth_event(e)]


def is_truth_notice(notice: dict[str, Any]) -> bool:
    """A WebSocket notice (``server.hub``) that tells the truth: an alarm on a truth
    channel, or its event."""
    if notice.get("type") == "alarm":
        return bool((notice.get("alarm") or {}).get("truth"))
    if notice.get("type") == "event":
        return is_truth_event(notice.get("event") or {})
    return False


def ground_channels(channels: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """Channel descriptions (or alarms and limits: anything with ``truth``) without the
    truth's."""
    return [c for c in channels if not c.get("truth")]
