"""The JSON form of the sequence language (docs/sequences.md, "JSON form").

``{"name": ..., "steps": [{"command": ..., "args": {...}, "time": {...}}]}`` or a bare list of
steps, read into the same ``Sequence`` the text form gives (``sequences.model``), every
problem reported with its location path (``steps[3].args.distance_m``) at the start of the
message. Numbers longer than ``MAX_NUMBER_CHARS`` and nesting deeper than ``MAX_JSON_DEPTH``
are refused before the decoder spends time on them.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from collections.abc import Mapping
from typing import Any

from sequences.commands import COMMANDS, MAX_WAIT_S, shown
from sequences.model import (
    COMMAND_FIELDS,
    MAX_NUMBER_CHARS,
    MAX_SOL,
    NAME_RE,
    NO_TAG,
    DiagnosticList,
    ParseResult,
    Sequence,
    SequenceError,
    SequenceStep,
    TimeTag,
    clock_s,
    unknown_arg,
    unknown_command,
)

MAX_JSON_DEPTH = 64  # where a JSON too deep for the decoder is reported (a sequence needs 4)
_A = re.ASCII


class _JsonObject(dict[str, Any]):
    """A JSON object that remembers keys given twice (``json`` keeps only the last)."""

    duplicates: list[str]


def _object_hook(pairs: list[tuple[str, Any]]) -> _JsonObject:
    obj = _JsonObject()
    obj.duplicates = []
    for key, value in pairs:
        if key in obj:
            obj.duplicates.append(key)
        obj[key] = value
    return obj


def parse_json(source: str | Mapping[str, Any] | list[Any]) -> ParseResult:
    """Parse the JSON form (text or already decoded): ``{"name": ..., "steps": [...]}``, or
    a bare list of steps. Problems carry the location (``steps[3].args.distance_m``) at the
    start of the message; line and column are 0 except for JSON syntax errors."""
    out = DiagnosticList()
    empty = ParseResult(Sequence(None, ()), out.diagnostics)
    data: Any = source
    if isinstance(source, str):
        try:
            data = json.loads(
                source,
                object_pairs_hook=_object_hook,
                parse_int=_json_int,
                parse_float=_json_float,
            )
        except json.JSONDecodeError as exc:
            out.error(exc.lineno, exc.colno, "bad-json", f"not valid JSON: {exc.msg}")
            return empty
        except _NumberTooLongError as exc:
            line, col = _json_where(source, _json_scan(source, number=exc.text))
            text = f"a number of {len(exc.text)} characters (at most {MAX_NUMBER_CHARS})"
            out.error(line, col, "bad-value", text)
            return empty
        except RecursionError:
            line, col = _json_where(source, _json_scan(source, number=None))
            text = f"not valid JSON: nested deeper than {MAX_JSON_DEPTH} levels"
            out.error(line, col, "bad-json", text)
            return empty
    if isinstance(data, list):
        data = {"steps": data}
    if not isinstance(data, Mapping):
        # decoded from text: the top-level value starts at the first non-blank character
        line, col = (
            _json_where(source, len(source) - len(source.lstrip(" \t\n\r")))
            if isinstance(source, str)
            else (0, 0)
        )
        out.error(line, col, "bad-structure", "a JSON sequence is an object with 'steps' (a list)")
        return empty
    _unknown_keys(data, ("name", "steps"), "", out)
    name = data.get("name")
    if name is not None and not (isinstance(name, str) and NAME_RE.fullmatch(name)):
        out.error(0, 0, "bad-name", "name: 1-64 letters, digits, _ or -")
        name = None
    raw_steps = data.get("steps")
    if not isinstance(raw_steps, list):
        out.error(0, 0, "bad-structure", "steps: must be a list of steps")
        return ParseResult(Sequence(name, ()), out.diagnostics)
    steps = [s for i, raw in enumerate(raw_steps) if (s := _json_step(raw, i, out)) is not None]
    if not raw_steps:
        out.error(0, 0, "empty", "steps: no commands")
    return ParseResult(Sequence(name, tuple(steps)), out.diagnostics)


class _NumberTooLongError(ValueError):
    """A JSON number longer than ``MAX_NUMBER_CHARS``, refused before ``int()`` (which
    raises past 4,300 digits) or ``float()`` see it."""

    def __init__(self, text: str) -> None:
        super().__init__("number too long")
        self.text = text


def _json_int(text: str) -> int:
    if len(text) > MAX_NUMBER_CHARS:
        raise _NumberTooLongError(text)
    return int(text)


def _json_float(text: str) -> float:
    if len(text) > MAX_NUMBER_CHARS:
        raise _NumberTooLongError(text)
    return float(text)


# Strings (skipped whole), numbers and brackets of a JSON text: enough to find where a
# decoder's error lies when the decoder cannot say (a too-long number, too deep nesting).
_JSON_SCAN_RE = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"|-?[0-9][0-9.eE+-]*|[\[{]|[\]}]', re.S | _A)


def _json_scan(source: str, number: str | None) -> int:
    """Offset in ``source`` of the number ``number`` (outside strings), or, when ``None``,
    of the first bracket nested deeper than ``MAX_JSON_DEPTH``; 0 if there is none. One
    pass: linear in the length of ``source``."""
    depth = 0
    for token in _JSON_SCAN_RE.finditer(source):
        first = token.group()[0]
        if number is not None:
            if first in "-0123456789" and token.group() == number:
                return token.start()
        elif first in "[{":
            depth += 1
            if depth > MAX_JSON_DEPTH:
                return token.start()
        elif first in "]}":
            depth -= 1
    return 0


def _json_where(source: str, offset: int) -> tuple[int, int]:
    """1-based line and column of ``offset``, counted as the JSON decoder counts them."""
    line = source.count("\n", 0, offset) + 1
    return line, offset - source.rfind("\n", 0, offset)


def _unknown_keys(
    obj: Mapping[str, Any], allowed: tuple[str, ...], where: str, out: DiagnosticList
) -> None:
    for key in obj:
        if key not in allowed:
            out.error(
                0,
                0,
                "bad-structure",
                f"{where}{_key(key)}: unknown key (allowed: {', '.join(allowed)})",
            )
    for key in getattr(obj, "duplicates", []):
        out.error(0, 0, "bad-structure", f"{where}{_key(key)}: given more than once")


def _key(key: object) -> str:
    """A JSON key in a location path: as it is if a plain name, else quoted and cut short."""
    return key if isinstance(key, str) and _PLAIN_KEY_RE.fullmatch(key) else shown(key)


_PLAIN_KEY_RE = re.compile(r"[A-Za-z0-9_]{1,40}", _A)


def _json_step(raw: object, i: int, out: DiagnosticList) -> SequenceStep | None:
    where = f"steps[{i}]"
    if not isinstance(raw, Mapping):
        out.error(0, 0, "bad-structure", f"{where}: must be an object with 'command'")
        return None
    _unknown_keys(raw, ("command", "args", "time"), f"{where}.", out)
    tag = _json_tag(raw.get("time"), f"{where}.time", out)
    keyword = raw.get("command")
    args = raw.get("args", {})
    if args is None:
        args = {}
    if not isinstance(args, Mapping):
        out.error(0, 0, "bad-structure", f"{where}.args: must be an object")
        return None
    for key in getattr(args, "duplicates", []):
        out.error(0, 0, "duplicate-argument", f"{where}.args.{_key(key)}: given more than once")
    if not isinstance(keyword, str):
        out.error(0, 0, "bad-structure", f"{where}.command: must be a command keyword")
        return None
    kind = COMMANDS.get(keyword)
    if kind is None:
        out.error(0, 0, "unknown-command", f"{where}.command: {unknown_command(keyword)}")
        return None
    names = {f.name for f in COMMAND_FIELDS[keyword]}
    bad = False
    for arg in args:
        if arg not in names:
            bad = True
            message = unknown_arg(keyword, _key(arg))
            out.error(0, 0, "unknown-argument", f"{where}.args.{message}")
    for f in COMMAND_FIELDS[keyword]:
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        if required and f.name not in args:
            bad = True
            out.error(0, 0, "missing-argument", f"{where}.args: {keyword} needs {f.name}")
    if bad or tag is None:
        return None
    try:
        command = kind(**{str(k): v for k, v in args.items()})
    except (ValueError, TypeError) as exc:
        out.error(0, 0, "bad-value", f"{where}.args.{exc}")
        return None
    return SequenceStep(0, 0, tag, command, where=where)


def _json_tag(raw: object, where: str, out: DiagnosticList) -> TimeTag | None:
    """The ``time`` of a JSON step: absent/null, ``{"lmst"}``, ``{"sol", "lmst"}`` or
    ``{"after_s"}``; ``None`` after reporting a problem."""
    if raw is None:
        return NO_TAG
    if not isinstance(raw, Mapping) or set(raw) not in ({"lmst"}, {"sol", "lmst"}, {"after_s"}):
        forms = '{"lmst": "hh:mm"}, {"sol": N, "lmst": "hh:mm"} or {"after_s": N}'
        out.error(0, 0, "bad-time-tag", f"{where}: must be {forms}")
        return None
    if "after_s" in raw:
        after = raw["after_s"]
        if isinstance(after, bool) or not isinstance(after, int | float):
            out.error(0, 0, "bad-time-tag", f"{where}.after_s: must be a number of seconds")
            return None
        finite = isinstance(after, int) or math.isfinite(after)  # isfinite(10**400) raises
        if not (finite and 0.0 <= after <= MAX_WAIT_S):
            out.error(0, 0, "bad-time-tag", f"{where}.after_s: must be 0 to {MAX_WAIT_S:.3f} s")
            return None
        return TimeTag("relative", after_s=float(after))
    lmst = raw["lmst"]
    lmst_s = clock_s(lmst, hours_max=23) if isinstance(lmst, str) else None
    if lmst_s is None:
        out.error(
            0, 0, "bad-time-tag", f"{where}.lmst: must be 'hh:mm' or 'hh:mm:ss', 00:00-23:59:59"
        )
        return None
    if "sol" not in raw:
        return TimeTag("lmst", lmst_s=lmst_s)
    sol = raw["sol"]
    if isinstance(sol, bool) or not isinstance(sol, int) or not 0 <= sol <= MAX_SOL:
        out.error(0, 0, "bad-time-tag", f"{where}.sol: must be a whole number 0 to {MAX_SOL}")
        return None
    return TimeTag("sol_lmst", lmst_s=lmst_s, sol=sol)


def to_json_data(sequence: Sequence) -> dict[str, Any]:
    """The JSON form of ``sequence`` as plain data (``None`` arguments are left out)."""
    steps: list[dict[str, Any]] = []
    for step in sequence.steps:
        item: dict[str, Any] = {"command": step.command.name}
        args = {k: v for k, v in step.command.arguments().items() if v is not None}
        if args:
            item["args"] = args
        tag = step.time_tag
        if tag.kind == "lmst":
            item["time"] = {"lmst": tag.clock()}
        elif tag.kind == "sol_lmst":
            item["time"] = {"sol": tag.sol, "lmst": tag.clock()}
        elif tag.kind == "relative":
            item["time"] = {"after_s": tag.after_s}
        steps.append(item)
    data: dict[str, Any] = {"name": sequence.name} if sequence.name else {}
    data["steps"] = steps
    return data


def to_json(sequence: Sequence, indent: int | None = 2) -> str:
    """The JSON form of ``sequence`` as text; ``from_json(to_json(s)) == s``."""
    return json.dumps(to_json_data(sequence), indent=indent)


def from_json(source: str | Mapping[str, Any] | list[Any]) -> Sequence:
    """The ``Sequence`` in a JSON source; ``SequenceError`` with every diagnostic."""
    result = parse_json(source)
    if result.diagnostics:
        raise SequenceError(result.diagnostics)
    return result.sequence
