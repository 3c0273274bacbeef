"""How ``roverops`` prints a command's result: JSON with ``--json``, else readable lines."""

from __future__ import annotations

import json
from typing import Any


def print_result(result: dict[str, Any], as_json: bool) -> None:
    """``result`` as JSON, or one ``key: value`` line each (a dict's entries indented)."""
    if as_json:
        print(json.dumps(result, indent=2))
        return
    for key, value in result.items():
        if isinstance(value, dict):
            print(f"{key}:")
            for sub_key, sub_value in value.items():
                print(f"  {sub_key}: {fmt(sub_value)}")
        else:
            print(f"{key}: {fmt(value)}")


def fmt(value: Any) -> str:
    """A value as a line shows it: floats to 6 significant digits."""
    if isinstance(value, float):
        return f"{round(value, 9) + 0.0:.6g}"  # so 1e-16 of a heading reads as 0, not -0
    if isinstance(value, list):
        return "[" + ", ".join(fmt(v) for v in value) + "]"
    return str(value)
