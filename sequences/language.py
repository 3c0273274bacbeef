"""The sequence language: text and JSON sequences to typed commands (``sequences.commands``).

docs/DESIGN.md sketches the format; ``docs/sequences.md`` is its precise definition (grammar,
commands, time tags, JSON form, diagnostics). This module is the syntax half: it turns a
source into a ``Sequence`` of ``SequenceStep`` (line, column, time tag, command) and collects
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
import json
import math
import re
import unicodedata
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

from sequences.commands import COMMANDS, MAX_WAIT_S, Command, shown

Severity = Literal["error", "warning"]
TagKind = Literal["none", "lmst", "sol_lmst", "relative"]

LMST_DAY_S = 86_400  # LMST clock seconds in one sol (a Mars "second" is 1/86400 sol)
MAX_SOL = 100_000  # far beyond any mission; catches typos such as a year for a sol
MAX_NUMBER_CHARS = 100  # a number longer than this is refused before it is converted
MAX_JSON_DEPTH = 64  # where a JSON too deep for the decoder is reported (a sequence needs 4)
NAME_RE = re.compile(r"[A-Za-z0-9_-]{1,64}")
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
_FIELDS = {name: tuple(dataclasses.fields(kind)) for name, kind in COMMANDS.items()}


@dataclass(frozen=True)
class Diagnostic:
    """One problem in a sequence: 1-based ``line`` and ``column`` (0 when unknown, as for
    most JSON problems, whose ``message`` then starts with the location, ``steps[3].args``),
    ``severity``, a stable ``code`` (listed in docs/sequences.md) and a one-line message."""

    line: int
    column: int
    severity: Severity
    code: str
    message: str

    def format(self, filename: str) -> str:
        """``FILE:LINE:COL: error CODE message``, the compiler-style line the CLI prints."""
        return f"{filename}:{self.line}:{self.column}: {self.severity} {self.code} {self.message}"

    def as_dict(self) -> dict[str, object]:
        """The diagnostic as a JSON-ready dict."""
        return dataclasses.asdict(self)


@dataclass(frozen=True)
class TimeTag:
    """When a step starts. ``kind``: ``none`` (when the previous command completes),
    ``lmst`` (the next time the LMST clock reads ``lmst_s``, this sol or later),
    ``sol_lmst`` (``lmst_s`` on sol ``sol``), ``relative`` (``after_s`` SI seconds after the
    previous command completes). ``lmst_s`` counts LMST clock seconds since local mean
    midnight, [0, 86400): whole seconds, so tags compare exactly."""

    kind: TagKind = "none"
    lmst_s: int | None = None
    sol: int | None = None
    after_s: float | None = None

    @property
    def lmst_h(self) -> float | None:
        """The LMST of an absolute tag in hours, or ``None``."""
        return None if self.lmst_s is None else self.lmst_s / 3600.0

    @property
    def absolute(self) -> bool:
        """True for the two LMST forms."""
        return self.kind in ("lmst", "sol_lmst")

    def clock(self) -> str:
        """The LMST as ``hh:mm`` or ``hh:mm:ss`` (empty for other kinds)."""
        if self.lmst_s is None:
            return ""
        h, rest = divmod(self.lmst_s, 3600)
        m, s = divmod(rest, 60)
        return f"{h:02d}:{m:02d}" + (f":{s:02d}" if s else "")


NO_TAG = TimeTag()


@dataclass(frozen=True)
class SequenceStep:
    """One command with its time tag. ``line``/``column`` locate the keyword in a text source
    (1-based; 0 for JSON), ``tag_column`` the ``@`` and ``where`` a JSON step (``steps[3]``);
    they do not take part in equality, so a sequence equals itself after a round trip
    through text or JSON."""

    line: int = field(compare=False)
    column: int = field(compare=False)
    time_tag: TimeTag
    command: Command
    tag_column: int = field(default=0, compare=False)
    where: str = field(default="", compare=False)


@dataclass(frozen=True)
class Sequence:
    """A parsed sequence: an optional ``name`` and its steps in order."""

    name: str | None
    steps: tuple[SequenceStep, ...]


@dataclass
class ParseResult:
    """What the parser found: the steps it could build and every diagnostic (errors only;
    warnings come from ``sequences.validate``). ``sequence`` is complete only when
    ``diagnostics`` is empty."""

    sequence: Sequence
    diagnostics: list[Diagnostic]


class SequenceError(ValueError):
    """A sequence with errors; ``diagnostics`` holds all of them."""

    def __init__(self, diagnostics: list[Diagnostic]) -> None:
        first = diagnostics[0]
        more = f" (and {len(diagnostics) - 1} more)" if len(diagnostics) > 1 else ""
        super().__init__(f"line {first.line}: {first.code}: {first.message}{more}")
        self.diagnostics = diagnostics


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


class _Lines:
    """Diagnostics collected while parsing, in source order."""

    def __init__(self) -> None:
        self.diagnostics: list[Diagnostic] = []

    def error(self, line: int, column: int, code: str, message: str) -> None:
        self.diagnostics.append(Diagnostic(line, column, "error", code, message))


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
    out = _Lines()
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


def _sequence_name(rest: str, line: int, col: int, out: _Lines) -> str | None:
    words = rest.split()
    if len(words) == 1 and NAME_RE.fullmatch(words[0]):
        return words[0]
    where = col + len(rest) - len(rest.lstrip())
    out.error(line, where, "bad-name", "SEQUENCE takes one name of 1-64 letters, digits, _ or -")
    return None


def _parse_line(body: str, col: int, number: int, out: _Lines) -> SequenceStep | None:
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
        out.error(number, kcol, "unknown-command", _unknown_command(keyword))
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


def _tag_from_match(match: re.Match[str], number: int, col: int, out: _Lines) -> TimeTag:
    clock, sol = match.group("clock"), match.group("sol")
    if clock is not None:
        lmst_s = _clock_s(clock, hours_max=23)
        if lmst_s is None:
            out.error(
                number, col, "bad-time-tag", f"LMST {clock} is not a time of day (00:00-23:59:59)"
            )
            return NO_TAG
        if sol is None:
            return TimeTag("lmst", lmst_s=lmst_s)
        sol = sol.lstrip("0") or "0"  # int() refuses over 4,300 digits: check the length first
        if len(sol) > len(str(MAX_SOL)) or int(sol) > MAX_SOL:
            out.error(number, col, "bad-time-tag", f"sol {_digits(sol)} is beyond {MAX_SOL}")
            return NO_TAG
        return TimeTag("sol_lmst", lmst_s=lmst_s, sol=int(sol))  # at most 6 digits here
    rel_clock, rel_s = match.group("rel_clock"), match.group("rel_s")
    too_long = rel_s is not None and len(rel_s) > MAX_NUMBER_CHARS
    after: float | None
    if rel_clock:
        after = _clock_s(rel_clock, hours_max=999)
    else:
        after = math.inf if too_long else float(rel_s)
    if after is None or after > MAX_WAIT_S:
        text = _digits(match.group()[1:].strip())
        why = "minutes and seconds are 00-59" if after is None else f"at most {MAX_WAIT_S:.3f} s"
        out.error(number, col, "bad-time-tag", f"relative tag {text}: {why}")
        return NO_TAG
    return TimeTag("relative", after_s=float(after))


def _digits(text: str) -> str:
    """``text`` for a message, a long run of digits cut to its ends and its length."""
    if len(text) <= 24:
        return text
    return f"{text[:10]}...{text[-6:]} ({len(text)} characters)"


def _clock_s(text: str, hours_max: int) -> int | None:
    """Seconds in ``hh:mm[:ss]``, or ``None`` if a field is out of range."""
    match = _CLOCK_RE.fullmatch(text)
    if match is None:
        return None
    h, m, s = int(match[1]), int(match[2]), int(match[3] or 0)
    if h > hours_max or m > 59 or s > 59:
        return None
    return 3600 * h + 60 * m + s


def _unknown_command(keyword: str) -> str:
    if keyword.upper() in COMMANDS:
        return f"unknown command {shown(keyword)}: keywords are upper case ({keyword.upper()})"
    if keyword == "SEQUENCE":
        return "SEQUENCE must be alone on the first line, without a time tag"
    if keyword.startswith("@"):
        return f"unknown command {shown(keyword)}: a time tag must start the line"
    return f"unknown command {shown(keyword)}"


_UNREADABLE = object()  # a value that did not parse (already reported)


class _Arg:
    __slots__ = ("column", "value")

    def __init__(self, value: object, column: int) -> None:
        self.value, self.column = value, column


def _arguments(tokens: list[tuple[str, int]], number: int, out: _Lines) -> dict[str, _Arg]:
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
    kind: type[Command], keyword: str, values: dict[str, _Arg], number: int, col: int, out: _Lines
) -> Command | None:
    """Construct the command; unknown, missing and bad arguments are reported (all of
    them), and ``None`` returned if any."""
    fields_ = _FIELDS[keyword]
    names = {f.name for f in fields_}
    ok = all(given.value is not _UNREADABLE for given in values.values())
    for arg, given in values.items():
        if arg not in names:
            ok = False
            out.error(
                number, given.column - len(arg) - 1, "unknown-argument", _unknown_arg(keyword, arg)
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


def _unknown_arg(keyword: str, arg: str) -> str:
    names = [f.name for f in _FIELDS[keyword]]
    takes = f"takes {', '.join(names)}" if names else "takes no arguments"
    return f"{arg}: unknown argument of {keyword} ({takes})"


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


# ---- the JSON form ---------------------------------------------------------------------


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
    out = _Lines()
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
    obj: Mapping[str, Any], allowed: tuple[str, ...], where: str, out: _Lines
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


def _json_step(raw: object, i: int, out: _Lines) -> SequenceStep | None:
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
        out.error(0, 0, "unknown-command", f"{where}.command: {_unknown_command(keyword)}")
        return None
    names = {f.name for f in _FIELDS[keyword]}
    bad = False
    for arg in args:
        if arg not in names:
            bad = True
            message = _unknown_arg(keyword, _key(arg))
            out.error(0, 0, "unknown-argument", f"{where}.args.{message}")
    for f in _FIELDS[keyword]:
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


def _json_tag(raw: object, where: str, out: _Lines) -> TimeTag | None:
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
    lmst_s = _clock_s(lmst, hours_max=23) if isinstance(lmst, str) else None
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
