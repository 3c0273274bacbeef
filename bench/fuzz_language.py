"""A hypothesis fuzzer of the sequence language: mutations of ``sequences/examples``.

Every input goes to ``sequences.validate.validate`` twice, without a context and with a
light one for Spirit built from ``sim`` (``server.validation.context.site_context``, sol 42,
AQF Fine), so the predicting walk and the sampled elevations are fuzzed too. Inputs are
the examples, text and JSON (and each in the other form), after one to four mutations:
characters inserted (ASCII punctuation, digits, no-break spaces, fullwidth digits, line
separators, control characters), spans deleted or duplicated, lines and tokens swapped,
numbers replaced by huge, negative, NaN-like or over-long ones, brackets nested deep, a
line repeated, a long run of one piece (quotes, digits, ``@``) on one line; and, for JSON,
values of the decoded form replaced (a 5,000-digit integer, a list nested 10,000 deep,
NaN, null, ...) and handed over decoded, as the server does. The slowest validation is
reported with its input: a scan quadratic in a line shows there first.

A *crash* is any exception. A diagnostic *without a line*: in a text source, a line outside
1..lines+1; in a JSON source, line 0 with no location (``steps[3]``, ``name``, a top-level
key) at the start of its message. ``roverops bench fuzz`` reports the figures.
"""

from __future__ import annotations

import copy
import json
import math
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from sequences.language import parse, split_lines, to_json, to_text
from sequences.validate import CODES, ValidationContext, validate

T = TypeVar("T")
EXAMPLES = Path(__file__).resolve().parents[1] / "sequences" / "examples"
MAX_FAILURES_KEPT = 5
SHOWN_CHARS = 300

_HUGE_DIGITS = "9" * 5000
NUMBERS = (
    _HUGE_DIGITS,
    "-" + "1" * 5000,
    "1" * 101,
    "1" * 100,
    "1e309",
    "-1e309",
    "1e-400",
    "NaN",
    "Infinity",
    "-Infinity",
    "nan",
    "inf",
    "0",
    "-0",
    "-1",
    "0.0",
    "4294967296",
    "9223372036854775808",
    "100000",
    "100001",
    "17668",
    "17669",
    "99999999999",
    "\uff11\uff12",
    "1_000",
    "0x10",
    ".",
    "-",
    "+.e5",
    "1.5e",
    "00000000000000000000000000000000000000000000007",
)
PIECES: tuple[str, ...] = (
    *' \t\n\r"#@=+-.:,{}[]0123456789eEs\\',
    "\u00a0",
    "\uff11",
    "\u2028",
    "\u0085",
    "\x00",
    "\x0b",
    "\x1c",
    "\u00e9",
    "\ufeff",
    "\U0001f680",
    "LMST",
    "sol ",
    "@ sol ",
    "@ +",
    "SEQUENCE ",
    "ARTICULATE_START\n",
    "HGA_PASS",
    '"',
    "\r\n",
    "//",
    "null",
    "true",
)
_TEXT_OPS = (
    "insert", "delete", "duplicate", "lines", "tokens", "number", "nest", "repeat", "flood",
)  # fmt: skip
FLOOD = ('"\\', "1", "a", "a=", "x ", "@", "#", '"', "=", "\t", ".", "e", "-", "\u00a0", "[")
FLOOD_TIMES = (100, 5000, 50_000)
NESTING = (1, 2, 10, 63, 64, 65, 999, 5000, 100_000)
REPEATS = (2, 10, 1000)
_NUMBER_RE = re.compile(r"-?\d+(?:\.\d+)?(?:[eE][+-]?\d+)?", re.ASCII)
_LOCATION_RE = re.compile(r"(?:steps\[\d+\]|steps|name)[.:]|'.*?': |[A-Za-z0-9_]{1,40}: ", re.S)


def _json_values() -> tuple[object, ...]:
    deep: list[Any] = []
    inner = deep
    for _ in range(10_000):
        inner.append([])
        inner = inner[0]
    return (
        10**5000,
        -(10**5000),
        10**400,
        2**63,
        -1,
        0,
        1.5,
        math.nan,
        math.inf,
        -math.inf,
        None,
        True,
        False,
        "",
        "x" * 10_000,
        "10:00",
        "99:99",
        "\u00a0",
        [],
        {},
        deep,
        {"sol": 17669, "lmst": "10:00"},
        {"sol": 10**5000, "lmst": "10:00"},
        {"after_s": math.nan},
        {"lmst": "24:00"},
        [{"command": "WAIT"}],
        {"command": "HGA_PASS", "args": {"duration_min": 120}},
    )


def _bases() -> list[str]:
    """The examples, text and JSON, each also in the other form."""
    bases: list[str] = []
    for path in sorted(EXAMPLES.iterdir()):
        text = path.read_text(encoding="utf-8")
        bases.append(text)
        sequence = parse(text)
        bases.append(to_text(sequence) if path.suffix == ".json" else to_json(sequence))
    return bases


@dataclass
class _Tally:
    """What the fuzzer found so far."""

    inputs: int = 0
    validations: int = 0
    crashes: int = 0
    without_line: int = 0
    unknown_codes: int = 0
    slowest_s: float = 0.0
    slowest_input: str = ""
    failures: list[dict[str, str]] = field(default_factory=list)

    def keep(self, kind: str, source: object, detail: str) -> None:
        if len(self.failures) < MAX_FAILURES_KEPT:
            shown = source if isinstance(source, str) else _safe_repr(source)
            self.failures.append(
                {"kind": kind, "input": repr(shown[:SHOWN_CHARS]), "detail": detail[:SHOWN_CHARS]}
            )


def _safe_repr(value: object) -> str:
    from sequences.commands import shown

    try:
        return json.dumps(value)[: SHOWN_CHARS * 2]
    except (ValueError, TypeError, RecursionError):
        return shown(value)


def _check(source: str | dict[str, Any], context: ValidationContext | None, tally: _Tally) -> None:
    tally.validations += 1
    t0 = time.process_time()
    try:
        result = validate(source, context)
    except Exception as exc:  # the fuzzer's whole point: count any exception
        tally.crashes += 1
        tally.keep("crash", source, f"{type(exc).__name__}: {exc}")
        return
    finally:
        spent = time.process_time() - t0
        if spent > tally.slowest_s:
            tally.slowest_s = spent
            shown = source if isinstance(source, str) else _safe_repr(source)
            tally.slowest_input = repr(shown[:SHOWN_CHARS]) + f" ({len(shown)} characters)"
    is_text = isinstance(source, str) and source.lstrip()[:1] not in ("{", "[")
    lines = sum(1 for _ in split_lines(source)) if is_text and isinstance(source, str) else 0
    for d in (*result.errors, *result.warnings):
        if d.code not in CODES:
            tally.unknown_codes += 1
            tally.keep("unknown code", source, f"{d.code}: {d.message}")
        located = (
            1 <= d.line <= lines + 1
            if is_text
            else (d.line >= 1 or _LOCATION_RE.match(d.message) is not None)
        )
        if not located:
            tally.without_line += 1
            tally.keep("no line", source, f"{d.line}:{d.column} {d.code} {d.message}")


def _int(data: Any, st: Any, lo: int, hi: int) -> int:
    """An integer in ``[lo, hi]`` drawn from hypothesis' ``data``."""
    value: int = data.draw(st.integers(lo, hi))
    return value


def _pick(data: Any, st: Any, options: Sequence[T]) -> T:
    """One of ``options``, drawn by index: hypothesis records (and may print) only ints."""
    return options[_int(data, st, 0, len(options) - 1)]


def _mutate_text(data: Any, st: Any, text: str) -> str:
    op = _pick(data, st, _TEXT_OPS)
    n = len(text)
    i = _int(data, st, 0, n)
    if op == "insert":
        return text[:i] + _pick(data, st, PIECES) + text[i:]
    if op in ("delete", "duplicate"):
        j = _int(data, st, i, min(n, i + 40))
        return text[:i] + text[j:] if op == "delete" else text[:j] + text[i:j] + text[j:]
    if op in ("lines", "tokens"):
        parts = text.split("\n") if op == "lines" else re.split(r"([ \t\n,:]+)", text)
        a = _int(data, st, 0, len(parts) - 1)
        b = _int(data, st, 0, len(parts) - 1)
        parts[a], parts[b] = parts[b], parts[a]
        return ("\n" if op == "lines" else "").join(parts)
    if op == "number":
        numbers = list(_NUMBER_RE.finditer(text))
        if not numbers:
            return text
        m = numbers[_int(data, st, 0, len(numbers) - 1)]
        return text[: m.start()] + _pick(data, st, NUMBERS) + text[m.end() :]
    if op == "flood":  # a long run on one line: quadratic scanning shows in the time
        return text[:i] + _pick(data, st, FLOOD) * _pick(data, st, FLOOD_TIMES) + text[i:]
    if op == "nest":
        return (
            text[:i] + _pick(data, st, ("[", "{", '{"a":[')) * _pick(data, st, NESTING) + text[i:]
        )
    lines = text.split("\n")
    k = _int(data, st, 0, len(lines) - 1)
    lines[k:k] = [lines[k]] * _pick(data, st, REPEATS)
    return "\n".join(lines)


def _mutate_json(data: Any, st: Any, decoded: Any, values: tuple[object, ...]) -> Any:
    """Replace one value somewhere in a decoded JSON sequence (top, step, args or time)."""
    steps = decoded.get("steps") if isinstance(decoded, dict) else None
    targets: list[Any] = [decoded]
    if isinstance(steps, list):
        targets += [s for s in steps if isinstance(s, dict)]
        for s in steps:
            if isinstance(s, dict):
                targets += [v for v in s.values() if isinstance(v, dict)]
    target = targets[_int(data, st, 0, len(targets) - 1)]
    keys = [*target.keys(), "extra", "time", "args", "sol"]
    key = keys[_int(data, st, 0, len(keys) - 1)]
    value = _pick(data, st, values)
    shallow = isinstance(value, dict) or (
        isinstance(value, list) and value and isinstance(value[0], dict)
    )
    target[key] = copy.deepcopy(value) if shallow else value  # later mutations edit dicts
    return decoded


def fuzz_language(n_inputs: int, seed: int) -> dict[str, Any]:
    """Run ``n_inputs`` mutated sequences through ``validate`` (each with and without a
    Spirit context) and return the ``language_fuzz_*`` figures: ``inputs``, ``crashes``
    (exceptions), ``diagnostics_without_line``, ``unknown_codes``, ``slowest_validation_s``
    (CPU) and ``failures`` (the first few, truncated). Deterministic for a ``seed``."""
    import hypothesis
    from hypothesis import strategies as st

    from server.validation.context import site_context
    from sim.world.marsclock import MISSIONS, t_s_for_sol_lmst

    spirit = MISSIONS["spirit"]
    context = site_context(
        "spirit",
        math.radians(spirit.lat_deg),
        math.radians(spirit.lon_east_deg),
        t_s_for_sol_lmst("spirit", 42, 8.0),
        aqf="Fine",
    )
    bases, values, tally = _bases(), _json_values(), _Tally()
    t0 = time.process_time()

    @hypothesis.seed(seed)
    @hypothesis.settings(
        max_examples=n_inputs,
        phases=[hypothesis.Phase.generate],
        database=None,
        deadline=None,
        suppress_health_check=list(hypothesis.HealthCheck),
    )
    @hypothesis.given(st.data())
    def one_input(data: Any) -> None:
        base = bases[_int(data, st, 0, len(bases) - 1)]
        source: str | dict[str, Any] = base
        if base.lstrip().startswith("{") and data.draw(st.booleans()):
            source = json.loads(base)
            for _ in range(_int(data, st, 1, 3)):
                source = _mutate_json(data, st, source, values)
        else:
            for _ in range(_int(data, st, 1, 4)):
                source = _mutate_text(data, st, str(source))
        tally.inputs += 1
        _check(source, None, tally)
        _check(source, context, tally)

    one_input()
    return {
        "language_fuzz_inputs": tally.inputs,
        "language_fuzz_validations": tally.validations,
        "language_fuzz_crashes": tally.crashes,
        "language_fuzz_diagnostics_without_line": tally.without_line,
        "language_fuzz_unknown_codes": tally.unknown_codes,
        "language_fuzz_slowest_validation_s": round(tally.slowest_s, 4),
        "language_fuzz_slowest_input": tally.slowest_input,
        "language_fuzz_cpu_s": round(time.process_time() - t0, 2),
        "language_fuzz_seed": seed,
        "language_fuzz_failures": tally.failures,
    }
