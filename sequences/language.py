"""The sequence language: text and JSON sequences to typed commands (``sequences.commands``).

docs/DESIGN.md sketches the format; ``docs/sequences.md`` is its precise definition (grammar,
commands, time tags, JSON form, diagnostics). This module is the syntax half and its front
door: it reads the text form (the JSON form is ``sequences.json_form``, the steps and
diagnostics ``sequences.model``, all importable from here), turns a source into a
``Sequence`` of ``SequenceStep`` (line, column, time tag, command) and collects
*every* problem it meets as a ``Diagnostic`` instead of stopping at the first, because an
operator fixing a sequence wants the whole list at once. Checks that need more than one line
(time order, Articulate state) and the warnings live in ``sequences.validate``.

The command dictionary is ``COMMANDS``; each command class checks its own arguments and its
``ValueError`` message starts with the argument's name, which is how a bad value is placed
at the right column. Nothing here knows about the rover's world (``sim``, ``server``).

>>> seq = parse("SEQUENCE demo\\n@ 10:00 LMST SUNCHECK_SUNGAZE\\nDRIVE_STRAIGHT distance_m=4")
>>> seq.name, [s.command.describe() for s in seq.steps]
('demo', ['SUNCHECK_SUNGAZE', 'DRIVE_STRAIGHT distance_m=4'])
>>> seq.steps[0].time_tag.lmst_h
10.0
>>> parse(to_text(seq)) == seq == from_json(to_json(seq))
True
"""

from __future__ import annotations

import dataclasses
import math
import re
import unicodedata
from collections.abc import Iterator, Mapping
from typing import Any

from sequences.commands import COMMANDS, MAX_WAIT_S, Command, shown
from sequences.json_form import MAX_JSON_DEPTH, from_json, parse_json, to_json, to_json_data
from sequences.model import (
    COMMAND_FIELDS,
    LMST_DAY_S,
    MAX_NUMBER_CHARS,
    MAX_SOL,
    NAME_RE,
    NO_TAG,
    Diagnostic,
    DiagnosticList,
    ParseResult,
    Sequence,
    SequenceError,
    SequenceStep,
    Severity,
    TagKind,
    TimeTag,
    clock_s,
    digits_for_message,
    unknown_arg,
    unknown_command,
)

# The language's front door: the model and the JSON form are read from here too.
__all__ = [
    "LMST_DAY_S",
    "MAX_JSON_DEPTH",
    "MAX_NUMBER_CHARS",
    "MAX_SOL",
    "NAME_RE",
    "NO_TAG",
    "Diagnostic",
    "ParseResult",
    "Sequence",
    "SequenceError",
    "SequenceStep",
    "Severity",
    "TagKind",
    "TimeTag",
    "declared_name",
    "format_value",
    "from_json",
    "parse",
    "parse_any",
    "parse_json",
    "parse_text",
    "parse_value",
    "split_lines",
    "to_json",
    "to_json_data",
    "to_text",
]


# The grammar is ASCII (docs/sequences.md): re.ASCII keeps \d and \s from matching
# fullwidth digits or a no-break space, which Python's Unicode classes would.
_A = re.ASCII
_CLOCK = r"(\d{1,2}):(\d{2})(?::(\d{2}))?"
_CLOCK_RE = re.compile(_CLOCK, _A)
_TAG_RE = re.compile(
    r"@[ \t]*(?:"
    r"(?:sol[ \t]+(?P<sol>\d+)[ \t]+)?(?P<clock>\d{1,2}:\d{2}(?::\d{2})?)[ \t]+LMST"
    r"|\+(?:(?P<rel_clock>\d{1,3}:\d{2}:\d{2})|(?P<rel_s>\d+(?:\.\d*)?|\.\d+)s)"
    r")(?=[ \t]|$)",
    _A,
)
# A string runs to its closing quote or to the end of the line (a lone final backslash
# included), so that the string branch cannot fail once started: a failing branch would be
# retried from every later quote, quadratic in the line.
_TOKEN_RE = re.compile(r'(?:[^ \t"]|"[^"\\]*(?:\\.[^"\\]*)*(?:"|\\?$))+', _A)
_ARG_RE = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)=(.*)", re.S | _A)
_INT_RE = re.compile(r"[+-]?\d+", _A)
# One way to split the digits only (not ``\d+\.?\d*``, which tries every split of a long
# digit run before failing on a letter after it: quadratic)
_FLOAT_RE = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?", _A)
_WORD_RE = re.compile(r"[A-Za-z_][A-Za-z0-9_.\-]*", _A)
_KEYWORD_RE = re.compile(r"[A-Z][A-Z0-9_]*", _A)
_LINE_END_RE = re.compile(r"\r\n|\r|\n")
_NOT_GRAMMAR_RE = re.compile(r"[^\t\x20-\x7e]")  # outside strings and comments
_DECLARATION_RE = re.compile(r"[ \t]*SEQUENCE[ \t]+([A-Za-z0-9_-]{1,64})[ \t]*(?:#.*)?", _A)
_BOOLEANS = {"on": True, "true": True, "off": False, "false": False}


def parse(source: str | Mapping[str, Any] | list[Any]) -> Sequence:
    """The ``Sequence`` in ``source`` (text, JSON text, or parsed JSON); ``SequenceError``
    with every diagnostic if it has errors."""
    result = parse_any(source)
    if result.diagnostics:
        raise SequenceError(result.diagnostics)
    return result.sequence


def parse_any(source: str | Mapping[str, Any] | list[Any]) -> ParseResult:
    """Parse text or JSON, told apart by the first character (``{`` or ``[`` is JSON)."""
    if isinstance(source, str) and source.lstrip()[:1] not in ("{", "["):
        return parse_text(source)
    return parse_json(source)


# ---- the text form ---------------------------------------------------------------------


def split_lines(text: str) -> Iterator[str]:
    """The lines of ``text``, ended by ``\\n``, ``\\r\\n`` or ``\\r`` (not by the other
    Unicode breaks ``str.splitlines`` knows), lazily; a final line end opens no new line.

    >>> list(split_lines("a\\r\\nb\\rc\\n")), list(split_lines("a\\u2028b"))
    (['a', 'b', 'c'], ['a\\u2028b'])
    """
    start = 0
    for end in _LINE_END_RE.finditer(text):
        yield text[start : end.start()]
        start = end.end()
    if start < len(text):
        yield text[start:]


def parse_text(text: str) -> ParseResult:
    """Parse the text form (grammar in docs/sequences.md), collecting every error. Work is
    linear in the length of ``text`` (one pass, per-line regular expressions)."""
    out = DiagnosticList()
    steps: list[SequenceStep] = []
    name: str | None = None
    seen_content = False
    for number, raw in enumerate(split_lines(text), start=1):
        body = _strip_comment(raw)
        stripped = body.lstrip(" \t")
        if not stripped:
            continue
        first_content, seen_content = not seen_content, True
        bad = _not_grammar(body)
        if bad is not None:  # the rest of the line is not read: it would only add noise
            out.error(number, bad + 1, "bad-character", _character_message(body[bad]))
            continue
        col = len(body) - len(stripped) + 1
        if stripped.startswith("SEQUENCE") and stripped[8:9] in ("", " ", "\t"):
            if not first_content:
                out.error(number, col, "sequence-not-first", "SEQUENCE must be the first line")
            else:
                name = _sequence_name(stripped[8:], number, col + 8, out)
            continue
        step = _parse_line(body, col, number, out)
        if step is not None:
            steps.append(step)
    if not steps and not out.diagnostics:
        out.error(1, 1, "empty", "no commands")
    return ParseResult(Sequence(name, tuple(steps)), out.diagnostics)


def _strip_comment(line: str) -> str:
    """``line`` without its ``#`` comment (a ``#`` inside a quoted string is kept)."""
    hash_at = line.find("#")
    if hash_at < 0:
        return line
    if '"' not in line[:hash_at]:
        return line[:hash_at]
    quoted = False
    i = 0
    while i < len(line):
        ch = line[i]
        if ch == "\\" and quoted:
            i += 2
            continue
        if ch == '"':
            quoted = not quoted
        elif ch == "#" and not quoted:
            return line[:i]
        i += 1
    return line


def _not_grammar(body: str) -> int | None:
    """Index of the first character of ``body`` (a line without its comment) that the
    grammar does not allow outside a quoted string: anything but printable ASCII and tab."""
    found = _NOT_GRAMMAR_RE.search(body)
    if found is None:
        return None
    if '"' not in body[: found.start()]:
        return found.start()
    quoted = False
    i = 0
    while i < len(body):
        ch = body[i]
        if ch == "\\" and quoted:
            i += 2
            continue
        if ch == '"':
            quoted = not quoted
        elif not quoted and _NOT_GRAMMAR_RE.match(ch):
            return i
        i += 1
    return None


def _character_message(ch: str) -> str:
    """Names a character the grammar refuses: ``non-ASCII character U+00A0 (NO-BREAK SPACE)``."""
    kind = "non-ASCII character" if ord(ch) > 0x7E else "control character"
    name = unicodedata.name(ch, "")
    named = f" ({name})" if name else ""
    return (
        f"{kind} U+{ord(ch):04X}{named}: outside quoted strings and comments a sequence is "
        "ASCII letters, digits, punctuation, spaces and tabs"
    )


def declared_name(source: str | Mapping[str, Any] | list[Any]) -> str | None:
    """The name a sequence declares (its first ``SEQUENCE name`` line, or the JSON
    ``name``) even when other lines have errors; ``None`` if it declares none. Linear in
    the length of the source (one regular expression per line, anchored to it).

    >>> declared_name("# sol 42\\n\\n  SEQUENCE sol42 # drive\\nPLANT_SITE"), declared_name([])
    ('sol42', None)
    """
    if isinstance(source, Mapping):
        name = source.get("name")
        return name if isinstance(name, str) and NAME_RE.fullmatch(name) else None
    if not isinstance(source, str):
        return None
    for line in split_lines(source):
        if "SEQUENCE" in line:
            found = _DECLARATION_RE.fullmatch(line)
            if found is not None:
                return found[1]
    return None


def _sequence_name(rest: str, line: int, col: int, out: DiagnosticList) -> str | None:
    words = rest.split()
    if len(words) == 1 and NAME_RE.fullmatch(words[0]):
        return words[0]
    where = col + len(rest) - len(rest.lstrip())
    out.error(line, where, "bad-name", "SEQUENCE takes one name of 1-64 letters, digits, _ or -")
    return None


def _parse_line(body: str, col: int, number: int, out: DiagnosticList) -> SequenceStep | None:
    tag, tag_col = NO_TAG, 0
    tokens = [(m.group(), m.start() + 1) for m in _TOKEN_RE.finditer(body)]
    if body[col - 1] == "@":
        tag_col = col
        match = _TAG_RE.match(body, col - 1)
        if match is not None:
            tag = _tag_from_match(match, number, col, out)
            tokens = [t for t in tokens if t[1] > match.end()]
        else:
            out.error(number, col, "bad-time-tag", _TAG_HELP)
            tokens = _after_bad_tag(tokens)
        if not tokens:
            out.error(number, col, "missing-command", "a time tag must be followed by a command")
            return None
    (keyword, kcol), args = tokens[0], tokens[1:]
    values = _arguments(args, number, out)
    kind = COMMANDS.get(keyword)
    if kind is None:
        out.error(number, kcol, "unknown-command", unknown_command(keyword))
        return None
    command = _build(kind, keyword, values, number, kcol, out)
    if command is None:
        return None
    return SequenceStep(number, kcol, tag, command, tag_col)


_TAG_HELP = (
    "malformed time tag: use @ hh:mm[:ss] LMST, @ sol N hh:mm[:ss] LMST, @ +hh:mm:ss or @ +Ns"
)


def _after_bad_tag(tokens: list[tuple[str, int]]) -> list[tuple[str, int]]:
    """Resume after a malformed tag at the first word that looks like a keyword, so the
    rest of the line is still checked."""
    for i, (token, _) in enumerate(tokens):
        if i > 0 and token != "LMST" and _KEYWORD_RE.fullmatch(token):
            return tokens[i:]
    return []


def _tag_from_match(match: re.Match[str], number: int, col: int, out: DiagnosticList) -> TimeTag:
    clock, sol = match.group("clock"), match.group("sol")
    if clock is not None:
        lmst_s = clock_s(clock, hours_max=23)
        if lmst_s is None:
            out.error(
                number, col, "bad-time-tag", f"LMST {clock} is not a time of day (00:00-23:59:59)"
            )
            return NO_TAG
        if sol is None:
            return TimeTag("lmst", lmst_s=lmst_s)
        sol = sol.lstrip("0") or "0"  # int() refuses over 4,300 digits: check the length first
        if len(sol) > len(str(MAX_SOL)) or int(sol) > MAX_SOL:
            out.error(
                number, col, "bad-time-tag", f"sol {digits_for_message(sol)} is beyond {MAX_SOL}"
            )
            return NO_TAG
        return TimeTag("sol_lmst", lmst_s=lmst_s, sol=int(sol))  # at most 6 digits here
    rel_clock, rel_s = match.group("rel_clock"), match.group("rel_s")
    too_long = rel_s is not None and len(rel_s) > MAX_NUMBER_CHARS
    after: float | None
    if rel_clock:
        after = clock_s(rel_clock, hours_max=999)
    else:
        after = math.inf if too_long else float(rel_s)
    if after is None or after > MAX_WAIT_S:
        text = digits_for_message(match.group()[1:].strip())
        why = "minutes and seconds are 00-59" if after is None else f"at most {MAX_WAIT_S:.3f} s"
        out.error(number, col, "bad-time-tag", f"relative tag {text}: {why}")
        return NO_TAG
    return TimeTag("relative", after_s=float(after))


_UNREADABLE = object()  # a value that did not parse (already reported)


class _Arg:
    __slots__ = ("column", "value")

    def __init__(self, value: object, column: int) -> None:
        self.value, self.column = value, column


def _arguments(tokens: list[tuple[str, int]], number: int, out: DiagnosticList) -> dict[str, _Arg]:
    """``name=value`` tokens to values; syntax errors and duplicates reported here."""
    values: dict[str, _Arg] = {}
    for token, col in tokens:
        match = _ARG_RE.fullmatch(token)
        if match is None:
            out.error(number, col, "syntax", f"expected name=value, got {shown(token)}")
            continue
        arg, text = match[1], match[2]
        vcol = col + len(arg) + 1
        try:
            value = parse_value(text)
        except ValueError as exc:
            out.error(number, vcol, "bad-value", f"{arg}: {exc}")
            value = _UNREADABLE
        if arg in values:
            out.error(number, col, "duplicate-argument", f"{arg}: given more than once")
            continue
        values[arg] = _Arg(value, vcol)
    return values


def parse_value(text: str) -> object:
    """One argument value: an int or float, a boolean (``on``/``off``/``true``/``false``,
    any case), a bare word or a double-quoted string (``\\"`` and ``\\\\`` escapes).

    >>> parse_value("4"), parse_value("-2.5e1"), parse_value("on"), parse_value("sungaze.timer_s")
    (4, -25.0, True, 'sungaze.timer_s')
    >>> parse_value('"a b"')
    'a b'
    """
    if not text:
        raise ValueError("missing value after '='")
    first = text[0]
    if first in "0123456789+-.":
        if len(text) > MAX_NUMBER_CHARS:  # no word starts so: a number, or nothing
            raise ValueError(f"a number of {len(text)} characters (at most {MAX_NUMBER_CHARS})")
        if _INT_RE.fullmatch(text):
            return int(text)
        if _FLOAT_RE.fullmatch(text):
            return float(text)
    elif first == '"':
        if len(text) < 2 or text[-1] != '"' or _odd_backslashes(text[:-1]):
            raise ValueError(f"unterminated string {text}")
        return re.sub(r"\\(.)", r"\1", text[1:-1])
    else:
        flag = _BOOLEANS.get(text.lower())
        if flag is not None:
            return flag
        if _WORD_RE.fullmatch(text):
            return text
    raise ValueError(
        f"{shown(text)} is not a number, on/off, true/false, word or quoted string "
        "(units go in the argument name, not the value)"
    )


def _odd_backslashes(text: str) -> bool:
    return (len(text) - len(text.rstrip("\\"))) % 2 == 1


def _build(
    kind: type[Command],
    keyword: str,
    values: dict[str, _Arg],
    number: int,
    col: int,
    out: DiagnosticList,
) -> Command | None:
    """Construct the command; unknown, missing and bad arguments are reported (all of
    them), and ``None`` returned if any."""
    fields_ = COMMAND_FIELDS[keyword]
    names = {f.name for f in fields_}
    ok = all(given.value is not _UNREADABLE for given in values.values())
    for arg, given in values.items():
        if arg not in names:
            ok = False
            out.error(
                number, given.column - len(arg) - 1, "unknown-argument", unknown_arg(keyword, arg)
            )
    for f in fields_:
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        if required and f.name not in values:
            ok = False
            out.error(number, col, "missing-argument", f"{keyword} needs {f.name}")
    if not ok:
        return None
    try:
        return kind(**{arg: given.value for arg, given in values.items()})
    except (ValueError, TypeError) as exc:
        message = str(exc)
        arg = message.split(":", 1)[0]
        where = values[arg].column if arg in values else col
        out.error(number, where, "bad-value", message)
        return None


def to_text(sequence: Sequence) -> str:
    """The text form of ``sequence``; ``parse(to_text(s)) == s``."""
    lines = [f"SEQUENCE {sequence.name}"] if sequence.name else []
    for step in sequence.steps:
        tag = _tag_text(step.time_tag)
        args = " ".join(
            f"{k}={format_value(v)}" for k, v in step.command.arguments().items() if v is not None
        )
        lines.append(" ".join(p for p in (tag, step.command.name, args) if p))
    return "\n".join(lines) + "\n"


def _tag_text(tag: TimeTag) -> str:
    if tag.kind == "lmst":
        return f"@ {tag.clock()} LMST"
    if tag.kind == "sol_lmst":
        return f"@ sol {tag.sol} {tag.clock()} LMST"
    if tag.kind == "relative":
        after = tag.after_s if tag.after_s is not None else 0.0
        return f"@ +{int(after) if after.is_integer() else repr(after)}s"
    return ""


def format_value(value: object) -> str:
    """An argument value as the text form writes it (``parse_value`` reads it back)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    text = str(value)
    if _WORD_RE.fullmatch(text) and text.lower() not in _BOOLEANS:
        return text
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'
