"""The sequence model: steps, time tags and the diagnostics the parsers collect.

A ``Sequence`` is a name and ``SequenceStep`` s (a time tag and a typed command from
``sequences.commands``); a ``Diagnostic`` is one problem, located by line and column. Both
forms of the language (text, ``sequences.language``; JSON, ``sequences.json_form``) build
these and report into a ``DiagnosticList``; the helpers here are the parts of the grammar
the two forms share (clock times, the names of unknown commands and arguments).
docs/sequences.md defines the language and lists the diagnostic codes.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from typing import Literal

from sequences.commands import COMMANDS, Command, shown

Severity = Literal["error", "warning"]
TagKind = Literal["none", "lmst", "sol_lmst", "relative"]

LMST_DAY_S = 86_400  # LMST clock seconds in one sol (a Mars "second" is 1/86400 sol)
MAX_SOL = 100_000  # far beyond any mission; catches typos such as a year for a sol
MAX_NUMBER_CHARS = 100  # a number longer than this is refused before it is converted
NAME_RE = re.compile(r"[A-Za-z0-9_-]{1,64}")
_CLOCK_RE = re.compile(r"(\d{1,2}):(\d{2})(?::(\d{2}))?", re.ASCII)
COMMAND_FIELDS = {name: tuple(dataclasses.fields(kind)) for name, kind in COMMANDS.items()}


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


class DiagnosticList:
    """Diagnostics collected while parsing, in source order."""

    def __init__(self) -> None:
        self.diagnostics: list[Diagnostic] = []

    def error(self, line: int, column: int, code: str, message: str) -> None:
        self.diagnostics.append(Diagnostic(line, column, "error", code, message))


def digits_for_message(text: str) -> str:
    """``text`` for a message, a long run of digits cut to its ends and its length."""
    if len(text) <= 24:
        return text
    return f"{text[:10]}...{text[-6:]} ({len(text)} characters)"


def clock_s(text: str, hours_max: int) -> int | None:
    """Seconds in ``hh:mm[:ss]``, or ``None`` if a field is out of range."""
    match = _CLOCK_RE.fullmatch(text)
    if match is None:
        return None
    h, m, s = int(match[1]), int(match[2]), int(match[3] or 0)
    if h > hours_max or m > 59 or s > 59:
        return None
    return 3600 * h + 60 * m + s


def unknown_command(keyword: str) -> str:
    if keyword.upper() in COMMANDS:
        return f"unknown command {shown(keyword)}: keywords are upper case ({keyword.upper()})"
    if keyword == "SEQUENCE":
        return "SEQUENCE must be alone on the first line, without a time tag"
    if keyword.startswith("@"):
        return f"unknown command {shown(keyword)}: a time tag must start the line"
    return f"unknown command {shown(keyword)}"


def unknown_arg(keyword: str, arg: str) -> str:
    names = [f.name for f in COMMAND_FIELDS[keyword]]
    takes = f"takes {', '.join(names)}" if names else "takes no arguments"
    return f"{arg}: unknown argument of {keyword} ({takes})"
