"""Events: what happened, in words for the operators, with a kind and a severity.

An event is made where it happens (the flight software here in ``estimation``, the rover
session in ``sim``) and keeps its kind and severity all the way to the console, so the
ground can filter the event log without parsing texts. The text is the operator's; it
never changes shape for the sake of a filter.

Kinds, by who makes them:

- flight software (``estimation.sapp.nate``): ``nadir`` (Nadir Update, Nadir Check),
  ``sunfind``, ``sungaze``, ``suncheck``, ``gyrocompass``, and ``acquisition`` (an
  attitude acquisition command, e.g. GetFineAttitude, done or aborted);
- the rover session (``sim.loop.session``): ``command`` (a command refused), ``site`` (a Site
  planted), ``parameter`` (a NATE parameter or a mobility limit set), ``hga`` (an HGA
  pass), ``vo`` (a visual odometry step), ``estimator`` (a comparison estimator stopped),
  ``mobility`` (mobility fault protection halted a drive, or the ground cleared the fault:
  ``estimation.protection``) and ``keepout`` (a keep-out zone added or cleared);
- the simulator (``sim.faults``): ``fault`` (a fault the test conductor injected, in the
  truth record only, never the downlink);
- the ground server (``server``): ``server`` (the server started, or restarted and the
  rover resumed from its checkpoint), ``sequence`` (a sequence started, completed or failed)
  and ``alarm`` (an alarm raised, escalated, cleared or acknowledged: ``error`` when
  critical, ``warning`` when a warning, ``info`` for a clear or an acknowledgement).

Severities, one rule for all kinds:

- ``error``: what was commanded did not happen: a command refused, a mode that failed
  (the flag dropped or the estimate was not updated), an acquisition aborted, an HGA pass
  whose margin went below zero, a drive halted by fault protection;
- ``warning``: it happened, degraded: a Sungaze without its gravity average, an HGA pass
  without a Fine attitude or with Earth setting, a VO step that fell back on wheel
  odometry, a Nadir Check that could not judge, a comparison estimator stopped;
- ``info``: everything else.

>>> Event("Site 1 planted", "site").as_dict()
{'text': 'Site 1 planted', 'kind': 'site', 'severity': 'info'}
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal

Severity = Literal["info", "warning", "error"]

SEVERITIES: tuple[Severity, ...] = ("info", "warning", "error")  # in increasing order

FLIGHT_KINDS = ("nadir", "sunfind", "sungaze", "suncheck", "gyrocompass", "acquisition")
SESSION_KINDS = (
    "command", "site", "parameter", "hga", "vo", "estimator", "mobility", "keepout",
)  # fmt: skip
SIMULATOR_KINDS = ("fault",)
SERVER_KINDS = ("server", "sequence", "alarm")
KINDS: tuple[str, ...] = FLIGHT_KINDS + SESSION_KINDS + SERVER_KINDS + SIMULATOR_KINDS


@dataclass(frozen=True)
class Event:
    """One event: ``text`` for the operators, ``kind`` one of ``KINDS``, ``severity`` one
    of ``SEVERITIES`` (module docstring for both vocabularies)."""

    text: str
    kind: str
    severity: Severity = "info"

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"event kind: {self.kind!r} is not one of {', '.join(KINDS)}")
        if self.severity not in SEVERITIES:
            raise ValueError(f"event severity: {self.severity!r} is not one of {SEVERITIES}")

    def as_dict(self) -> dict[str, str]:
        """``{"text", "kind", "severity"}``: the event as a telemetry frame carries it."""
        return {"text": self.text, "kind": self.kind, "severity": self.severity}


def failure_severity(success: bool) -> Severity:
    """``info`` for a mode that succeeded, ``error`` for one that failed."""
    return "info" if success else "error"


def parameter_text(name: str, value: float | bool) -> str:
    """The text of the event that reports a NATE parameter set (SET_PARAM)."""
    return f"parameter {name} = {value}"


_PARAMETER = re.compile(r"parameter ([\w.]+) = (\S+)")  # dotted: vo.rig, mobility.*


def reported_parameter(text: str) -> tuple[str, float] | None:
    """The parameter and numeric value a ``parameter_text`` reports (``None``: another
    text, or a value that is not a number). A boolean reads as 0.0 or 1.0.

    >>> reported_parameter(parameter_text("min_sun_elevation_rad", 0.1))
    ('min_sun_elevation_rad', 0.1)
    >>> reported_parameter(parameter_text("vo.rig", 1024))
    ('vo.rig', 1024.0)
    >>> reported_parameter("Site 1 planted") is None
    True
    """
    found = _PARAMETER.fullmatch(text)
    if found is None:
        return None
    value = {"True": "1", "False": "0"}.get(found[2], found[2])
    try:
        return found[1], float(value)
    except ValueError:
        return None
