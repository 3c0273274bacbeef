"""Checkpoint state as plain data: the helpers every stateful flight-software class uses.

The contract (the runtime's checkpoints): ``state()`` returns plain data only (``None``,
bool, int, float, str, lists, str-keyed dicts, numpy arrays; never an object of ours, never
a class name), and ``load_state(state)`` loads it onto an object freshly built from the
same configuration. Parameter dataclasses travel as nested dicts of their fields and come
back through the fresh object's own parameters (``load_params``), so that the dataclasses'
checks run again and a renamed class does not break an old checkpoint.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, TypeVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
P = TypeVar("P")


def params_state(params: Any) -> dict[str, Any]:
    """A parameter dataclass as a dict of plain values (nested dataclasses as dicts, tuples
    as lists)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(params):
        value = getattr(params, f.name)
        if dataclasses.is_dataclass(value) and not isinstance(value, type):
            out[f.name] = params_state(value)
        elif isinstance(value, tuple):
            out[f.name] = list(value)
        else:
            out[f.name] = value
    return out


def load_params(template: P, state: Mapping[str, Any]) -> P:
    """``template`` (a parameter dataclass of the right type) with the values of ``state``
    (``params_state``'s output); the dataclass checks them again."""
    changes: dict[str, Any] = {}
    for f in dataclasses.fields(template):  # type: ignore[arg-type]
        current = getattr(template, f.name)
        value = state[f.name]
        if dataclasses.is_dataclass(current) and not isinstance(current, type):
            changes[f.name] = load_params(current, value)
        elif isinstance(current, tuple):
            changes[f.name] = tuple(value)
        else:
            changes[f.name] = value
    return dataclasses.replace(template, **changes)  # type: ignore[type-var]


def array_copy(value: ArrayLike | None) -> FloatArray | None:
    """A float copy of an array (for ``state()`` and ``load_state()``), ``None`` kept."""
    if value is None:
        return None
    return np.array(value, dtype=np.float64)
