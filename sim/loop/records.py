"""What the telemetry records have in common: each field's unit and meaning for the schema,
and the record as the JSON-ready dict the server sends and stores.

The two records are ``sim.loop.downlink.Downlink`` (what the rover itself reports) and
``sim.scoring.truth.Truth`` (what only the simulator knows, and the scores of the estimate
against it). Each is a plain frozen dataclass whose fields carry pydantic metadata
(``Annotated[..., Field(description=...)]``): the schema reads the descriptions, and a record,
built once per kept control cycle, pays no validation on construction.
"""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

from pydantic import Field, TypeAdapter
from typing_extensions import TypedDict  # pydantic validates it (tests) on Python 3.11

from estimation.events import Event

Vec3 = list[float]
Quat = list[float]


class EventDict(TypedDict):
    """An ``estimation.events.Event`` in a JSON-ready record."""

    text: str
    kind: str
    severity: str


def about(text: str) -> Any:
    """A field's meaning and unit, for the schema."""
    return Field(description=text)


def record_fields(record_type: type) -> list[str]:
    """A record type's field names, in order (the CSV columns, the tests' keys)."""
    return [f.name for f in fields(record_type)]


def record_schema(record_type: type) -> dict[str, Any]:
    """The JSON schema of a record as the server sends it (``record_dict``)."""
    return TypeAdapter(record_type).json_schema(mode="serialization")


def record_dict(record: Any, names: tuple[str, ...]) -> dict[str, Any]:
    """``record``'s fields ``names`` as a JSON-ready dict (what ``dataclasses.asdict`` gives,
    built without its deep copy: the server turns every stored record into one); a figure
    that does not exist (NaN, e.g. the accelerometer tilt of a cycle without a sample) is
    ``None``: JSON has no NaN."""
    out: dict[str, Any] = {}
    for name in names:
        value = getattr(record, name)
        if type(value) is float:
            out[name] = value if math.isfinite(value) else None
        else:
            out[name] = _plain(value)
    return out


def _plain(value: Any) -> Any:
    """``value`` as ``dataclasses.asdict`` copies it: lists, tuples and dicts anew, an
    ``Event`` as its dict, numbers and strings as they are."""
    kind = type(value)
    if kind is list or kind is tuple:
        return kind(v if type(v) in _ATOMS else _plain(v) for v in value)
    if kind is dict:
        return {k: v if type(v) in _ATOMS else _plain(v) for k, v in value.items()}
    if kind is Event:
        return {"text": value.text, "kind": value.kind, "severity": value.severity}
    return value


_ATOMS = (float, int, str, bool, type(None))
