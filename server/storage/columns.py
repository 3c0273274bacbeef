"""The two telemetry records as table columns, generated from their types.

Each numeric field of a record (``sim.loop.downlink.Downlink``, ``sim.scoring.truth.Truth``)
is one nullable ``Double`` column named after it; a list of numbers is one column per
component, ``q_b_ll_est_0`` ... (the telemetry CSV's and ``server.channels``' names, with
the lengths ``server.channels.vector_length`` gives). A channel query then reads one column
over an index on time instead of every frame's JSON (issue 21). Everything else of the
record (its events, the side estimators, the command, NATE's mode, the AQF), and any value
that does not fit its column exactly, is kept in the row's JSON ``data`` column, so a record
comes back as it was stored:

- NaN, infinities and ``None`` are a null column and read back as ``None`` (JSON has no NaN:
  the package's rule);
- an integer field (``site_index``) reads back as an ``int``, a float field as a ``float``;
- a list field stored with a wrong length, or with no finite component at all, stays whole
  in ``data``, so a list whose components are all null means "not in the record" and reads
  back as ``None``, as does a numeric field the record lacked (a frame of an older version);
- a non-numeric field the record lacked reads back as the record type's default (``events``:
  ``[]``), else ``None``; keys that are not fields of the record are kept as they are.

A field added to a record gets its column here, and an existing database gets it when it is
opened (``server.storage.schema.upgrade_schema`` adds the missing columns).
"""

from __future__ import annotations

import math
import typing
from collections.abc import Mapping, Sequence
from dataclasses import MISSING, dataclass, fields
from typing import Any

from sqlalchemy import Column, Double

from server.channels import vector_length
from sim.loop.downlink import Downlink
from sim.scoring.truth import Truth

# the columns a frame row has besides the record's own (its key, rover, JSON rest, layout)
RESERVED = frozenset({"id", "rover", "t_s", "sol", "data", "layout"})


@dataclass(frozen=True)
class NumericField:
    """A numeric field of a record and its columns: ``(name,)`` for a number, ``name_0``
    ... for a list of numbers."""

    name: str
    integer: bool
    length: int | None  # None: a single number

    @property
    def columns(self) -> tuple[str, ...]:
        if self.length is None:
            return (self.name,)
        return tuple(f"{self.name}_{i}" for i in range(self.length))


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _finite_or_none(value: Any) -> float | None:
    x = float(value)
    return x if math.isfinite(x) else None


class RecordColumns:
    """How the records of one type become a row's columns and come back (module docstring).
    ``in_row``: the fields the table keeps in columns of its own (``t_s``, the downlink's
    ``sol``), which are neither generated nor kept in ``data``."""

    def __init__(self, record: type, in_row: tuple[str, ...]) -> None:
        hints = typing.get_type_hints(record)
        self.names = tuple(f.name for f in fields(record))
        self.in_row = in_row
        self.numeric: dict[str, NumericField] = {}
        self.defaults: dict[str, Any] = {}
        for f in fields(record):
            hint = hints[f.name]
            if f.default_factory is not MISSING:
                self.defaults[f.name] = f.default_factory
            if f.name in in_row:
                continue
            if hint in (float, int):
                self.numeric[f.name] = NumericField(f.name, hint is int, None)
            elif typing.get_origin(hint) is list and typing.get_args(hint) == (float,):
                self.numeric[f.name] = NumericField(f.name, False, vector_length(f.name))
        self.columns = tuple(c for n in self.numeric.values() for c in n.columns)
        # each numeric field and the index of its first column in ``columns``
        self.spans: dict[str, tuple[NumericField, int]] = {}
        at = 0
        for name, numeric in self.numeric.items():
            self.spans[name] = (numeric, at)
            at += len(numeric.columns)
        clash = RESERVED.intersection(self.columns)
        if clash:
            raise ValueError(f"{record.__name__}: fields named as a frame row's columns: {clash}")

    def table_columns(self) -> list[Column[Any]]:
        """A nullable ``Double`` column for each generated column name."""
        return [Column(name, Double, nullable=True) for name in self.columns]

    def encode(self, record: Mapping[str, Any]) -> dict[str, Any]:
        """The generated columns' values of ``record`` and its ``data`` (the rest)."""
        row: dict[str, Any] = dict.fromkeys(self.columns)
        rest: dict[str, Any] = {}
        for key, value in record.items():
            if key in self.in_row:
                continue
            field = self.numeric.get(key)
            if field is None or not self._put(field, value, row):
                rest[key] = value
        row["data"] = rest
        return row

    @staticmethod
    def _put(field: NumericField, value: Any, row: dict[str, Any]) -> bool:
        """Put ``value`` in ``field``'s columns of ``row``; False if it does not fit them."""
        if value is None:
            return True
        if field.length is None:
            if not _number(value) or (field.integer and not isinstance(value, int)):
                return False
            row[field.name] = _finite_or_none(value)
            return True
        if not isinstance(value, list | tuple) or len(value) != field.length:
            return False
        if not all(x is None or _number(x) for x in value):
            return False
        parts = [None if x is None else _finite_or_none(x) for x in value]
        if all(x is None for x in parts):
            return False  # kept whole: all-null columns mean "not in the record"
        row.update(zip(field.columns, parts, strict=True))
        return True

    def decode(
        self, in_row: Mapping[str, Any], values: Sequence[Any], rest: Mapping[str, Any]
    ) -> dict[str, Any]:
        """The record from its row: ``in_row`` (``t_s``, ...), the generated columns'
        ``values`` in ``columns`` order and its ``data``, in the record's field order."""
        out: dict[str, Any] = {}
        spans = self.spans
        for name in self.names:
            if name in in_row:
                out[name] = in_row[name]
            elif name in rest:
                out[name] = rest[name]
            elif name in spans:
                field, at = spans[name]
                if field.length is None:
                    x = values[at]
                    out[name] = None if x is None else int(x) if field.integer else float(x)
                else:
                    parts = values[at : at + field.length]
                    out[name] = None if all(x is None for x in parts) else list(parts)
            else:
                factory = self.defaults.get(name)
                out[name] = factory() if factory is not None else None
        for key, value in rest.items():
            if key not in out:
                out[key] = value
        return out


DOWNLINK = RecordColumns(Downlink, in_row=("t_s", "sol"))
TRUTH = RecordColumns(Truth, in_row=("t_s",))
