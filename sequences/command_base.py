"""The base of the command dictionary: an argument's spec, and the command dataclass that
checks its arguments on construction (``sequences.commands`` holds the commands
themselves). Messages show values through ``shown``, which cuts any value short.
"""

from __future__ import annotations

import math
import numbers
import reprlib
from collections.abc import Mapping
from dataclasses import MISSING, dataclass, fields
from typing import ClassVar, Literal

ArgKind = Literal["number", "boolean", "string", "number_or_boolean"]


class _Short(reprlib.Repr):
    """``repr`` cut short, for messages: strings and containers shortened, nesting depth
    bounded, and an integer too long for ``repr`` (over 4,300 digits) described instead."""

    def __init__(self) -> None:
        super().__init__()
        self.maxstring = self.maxother = self.maxlong = 40
        self.maxlevel = 3

    def repr_int(self, x: int, level: int) -> str:
        if x.bit_length() > 128:
            sign = "a negative" if x < 0 else "an"
            return f"{sign} integer of about {int(x.bit_length() * math.log10(2)) + 1} digits"
        return super().repr_int(x, level)


_SHORT = _Short()


def shown(value: object) -> str:
    """``value`` as a message shows it: its ``repr``, at most about 40 characters, for any
    value (a 5,000-digit integer or a list nested a thousand deep included).

    >>> shown(1.5), shown("x" * 100)[:12], shown(10**5000)
    ('1.5', "'xxxxxxxxxxx", 'an integer of about 5001 digits')
    """
    return _SHORT.repr(value)


@dataclass(frozen=True)
class ArgSpec:
    """One argument as the dictionary publishes it and construction checks it.

    ``number``: a real number in ``[lo, hi] unit`` (``(lo, hi]`` when ``lo_open``).
    ``boolean``: true or false. ``number_or_boolean``: either; the number finite.
    ``string``: text whose meaning the command checks in its rules (``note`` says it).
    ``note``: what the range cannot say (rules across arguments, sign conventions).
    An argument whose default is ``None`` may be omitted: the rover uses its parameter."""

    kind: ArgKind
    unit: str = ""
    lo: float | None = None
    hi: float | None = None
    lo_open: bool = False
    note: str = ""

    def __post_init__(self) -> None:
        numeric = self.kind == "number"
        if numeric != (self.lo is not None and self.hi is not None) or (numeric and not self.unit):
            raise TypeError(f"ArgSpec: a number has lo, hi and a unit; got {self!r}")

    def range_text(self) -> str:
        """``(lo, hi] unit`` as in the error messages; ``""`` for a non-number."""
        if self.lo is None or self.hi is None:
            return ""
        left = "(" if self.lo_open else "["
        return f"{left}{self.lo:g}, {self.hi:g}] {self.unit}"

    def contains(self, value: float) -> bool:
        """Whether ``value`` (finite) lies in the range; ``False`` for a non-number spec."""
        if self.lo is None or self.hi is None or not math.isfinite(value):
            return False
        return (value > self.lo if self.lo_open else value >= self.lo) and value <= self.hi

    def check(self, name: str, value: object) -> None:
        """Raise ``ValueError`` naming ``name`` unless ``value`` is of this kind and range."""
        if self.kind == "number":
            _check_number(name, value, self)
        elif self.kind == "boolean" and not isinstance(value, bool):
            raise ValueError(f"{name}: must be true or false, got {shown(value)}")
        elif self.kind == "number_or_boolean" and not isinstance(value, bool):
            _finite_number_or_boolean(name, value)


def _check_number(name: str, value: object, spec: ArgSpec) -> None:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: must be a number, got {shown(value)}")
    try:
        v = float(value)
    except OverflowError:  # an int beyond float
        v = math.inf
    if not spec.contains(v):
        raise ValueError(f"{name}: must be in {spec.range_text()}, got {shown(value)}")


def _finite_number_or_boolean(name: str, value: object) -> None:
    if not isinstance(value, numbers.Real):
        raise ValueError(f"{name}: must be a number or true/false, got {shown(value)}")
    try:
        finite = math.isfinite(float(value))
    except OverflowError:
        finite = False
    if not finite:
        raise ValueError(f"{name}: must be finite, got {shown(value)}")


@dataclass(frozen=True)
class Argument:
    """One argument of a command for the dictionary: its spec, and whether it may be
    omitted (``default``, ``None`` meaning the rover's parameter)."""

    name: str
    spec: ArgSpec
    required: bool
    default: object


@dataclass(frozen=True)
class Command:
    """Base of every command: ``name`` is the sequence-language keyword; ``specs`` holds an
    ``ArgSpec`` per argument, in field order."""

    name: ClassVar[str] = ""
    specs: ClassVar[Mapping[str, ArgSpec]] = {}
    # What NATE does with the command (Ali et al. 2005; ``estimation.sapp.nate``), for the
    # ground's checks and predictions (``sequences.validate``): accepted while articulating
    # (sec. 2.4.1), refused with the sun below its minimum elevation (the camera modes'
    # sanity check), and the Attitude Quality Flag a success leaves (sec. 2.1).
    in_articulate: ClassVar[bool] = False
    images_sun: ClassVar[bool] = False
    aqf_after: ClassVar[str | None] = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None and f.default is None:
                continue  # omitted: the rover uses its parameter
            self.specs[f.name].check(f.name, value)
        self._check_rules()

    def _check_rules(self) -> None:
        """Rules a range cannot express; the arguments' ``note`` describes them."""

    @classmethod
    def argument_table(cls) -> tuple[Argument, ...]:
        """Every argument with its spec, in field order (what ``GET /api/commands`` shows)."""
        return tuple(
            Argument(
                f.name,
                cls.specs[f.name],
                required=f.default is MISSING,
                default=None if f.default is MISSING else f.default,
            )
            for f in fields(cls)
        )

    def arguments(self) -> dict[str, object]:
        """The arguments as a plain dict (for telemetry and storage)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def describe(self) -> str:
        """``NAME arg=value ...`` as in a sequence file."""
        args = " ".join(
            f"{k}={str(v).lower() if isinstance(v, bool) else v}"  # on/off as the language
            for k, v in self.arguments().items()
            if v is not None
        )
        return f"{self.name} {args}".strip()
