"""The event log of a rover: every stored event, filtered and paged for the console.

Events are stored with their kind and severity (``estimation.events``; those stored before
they had them are kind ``unknown``, severity ``info``). Over REST each event is
``{"t_s", "utc", "lmst_h", "sol", "text", "kind", "severity"}``, as in the sol timeline.
"""

from __future__ import annotations

from typing import Any

from server.runtime import RoverRuntime
from sim.marsclock import t_s_to_utc


def rest_event(runtime: RoverRuntime, event: dict[str, Any]) -> dict[str, Any]:
    """A stored event (``Store.events``) with its times at ``runtime``'s site."""
    t_s = float(event["t_s"])
    return {
        "t_s": t_s,
        "utc": t_s_to_utc(t_s).isoformat(),
        "lmst_h": runtime.lmst_h(t_s),
        "sol": runtime.sol(t_s),
        "text": event["text"],
        "kind": event["kind"],
        "severity": event["severity"],
    }
