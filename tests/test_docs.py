"""The docs point only at what is in the repository (issue 14, item 10).

The README pointed to a ``CONVENTIONS.md`` and the code to a ``DESIGN.md`` that were not in
the repository. Here: every relative link of README.md and docs/*.md, and every backticked
file name in them (``*.md`` anywhere; a path with a ``/`` and a source suffix), names a
file that exists; the code's pointers to the design and the conventions name the files in
docs/; and pyproject's licence is an SPDX string (a TOML table made setuptools print a
deprecation banner on every install).
"""

from __future__ import annotations

import calendar
import re
import tomllib
from pathlib import Path

import pytest

from tests.test_layout import OUTSIDE

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")
BACKTICKED = re.compile(r"`([^`\s]+)`")
SOURCE = re.compile(r"^[\w.-]+(/[\w.-]+)+\.(py|md|seq|json|js|html|css|toml)$")


def _targets(doc: Path) -> list[str]:
    """What ``doc`` points at: relative links, backticked ``*.md`` names and paths."""
    text = re.sub(r"```.*?```", "", doc.read_text(), flags=re.DOTALL)  # code blocks aside
    found = [t.split("#")[0] for t in LINK.findall(text)]
    found = [t for t in found if t and not re.match(r"^[a-z]+:", t)]  # http:, mailto:
    for name in BACKTICKED.findall(text):
        if name.endswith(".md") or SOURCE.match(name):
            found.append(name)
    return found


def _exists(doc: Path, target: str) -> bool:
    """A target is found beside the doc or from the repository's root."""
    return (doc.parent / target).exists() or (ROOT / target).exists()


def test_the_docs_are_found() -> None:
    names = {d.name for d in DOCS}
    assert {"README.md", "DESIGN.md", "CONVENTIONS.md", "sequences.md"} <= names
    readme = _targets(ROOT / "README.md")
    assert "docs/DESIGN.md" in readme and "docs/CONVENTIONS.md" in readme


@pytest.mark.parametrize("doc", DOCS, ids=lambda d: d.name)
def test_every_file_a_doc_names_exists(doc: Path) -> None:
    missing = [t for t in _targets(doc) if not _exists(doc, t)]
    assert missing == [], f"{doc.relative_to(ROOT)} names files not in the repository"


def test_the_checker_sees_a_missing_file(tmp_path: Path) -> None:
    doc = tmp_path / "README.md"
    doc.write_text("See `CONVENTIONS.md`, [the design](docs/NOPE.md) and `server/nope.py`.\n")
    assert [t for t in _targets(doc) if not _exists(doc, t)] == [
        "docs/NOPE.md",
        "CONVENTIONS.md",
        "server/nope.py",
    ]


def test_the_docs_point_nowhere_outside_the_repository() -> None:
    # every tracked file is checked by tests/test_layout.py; the docs here even untracked
    for doc in DOCS:
        assert OUTSIDE.search(doc.read_bytes()) is None, doc.name


def test_the_codes_pointers_to_the_design_and_conventions_are_docs_files() -> None:
    pointer = re.compile(r"(?<![\w/])([\w./]*)(DESIGN|CONVENTIONS)\.md")
    wrong = []
    for package in ("estimation", "sim", "server", "sequences", "bench", "cli", "tests", "web"):
        for path in sorted((ROOT / package).rglob("*")):
            if path.suffix not in (".py", ".js", ".html", ".seq") or path == Path(__file__):
                continue
            for prefix, name in pointer.findall(path.read_text()):
                if prefix != "docs/":
                    wrong.append(f"{path.relative_to(ROOT)}: {prefix}{name}.md")
    assert wrong == []
    assert (ROOT / "docs" / "DESIGN.md").is_file() and (ROOT / "docs" / "CONVENTIONS.md").is_file()


def test_the_licence_is_an_spdx_string() -> None:
    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert isinstance(pyproject["project"]["license"], str)
    assert pyproject["project"]["license"] == "MIT"
    # an SPDX string needs setuptools 77 (PEP 639); an older one would refuse the build
    requires = pyproject["build-system"]["requires"]
    assert any(re.fullmatch(r"setuptools>=(7[7-9]|[89]\d|\d{3,})(\.\d+)*", r) for r in requires)


# An author-year citation: authors (``Ali et al.``, ``Cheng, Maimone and Matthies``,
# ``Golombek & Rapp``, ``IAU/IAG``) then a year, maybe in a parenthesis; a date (``2004-04``)
# is not one, nor a month (``the February 2005 flight software``).
CITATION = re.compile(
    r"(?<![\w/])((?:[A-Z][\w'-]+|[A-Z]{2,}/[A-Z]{2,})(?:(?:, | and | & )[A-Z][\w'-]+)*"
    r"(?: et al\.?)?),? \(?((?:1[89]|20)\d\d)\b(?!-\d)"
)
MONTHS = {*calendar.month_name[1:], *calendar.month_abbr[1:], "Sept"}


def citations(text: str) -> set[tuple[str, str]]:
    """``(first author, year)`` of every author-year citation in ``text``, lines joined
    (a citation may wrap, in a docstring or in ``#`` comments)."""
    joined = re.sub(r"\s*\n\s*(?:#+|//+)?\s*", " ", text)
    found = set()
    for authors, year in CITATION.findall(joined):
        names = [n for n in re.split(r", | and | & | et al", authors) if n]
        # the first that reads as a surname: "RANSAC, Fischler and Bolles" is Fischler's
        first = next((n for n in names if re.match(r"[A-Z][a-z]", n)), names[0])
        if first not in MONTHS:
            found.add((first, year))
    return found


def test_the_citation_finder() -> None:
    text = (
        "(Ali et al. 2005, sec. 2) and Cheng, Maimone and\n    Matthies 2005; Golombek & Rapp"
        " (1997, JGR); Jiang, Li\n# et al. 2014; IAU/IAG 2000; Van Loan 1978; the February 2005"
        " software; Gusev, 2004-04-14 16:30 UTC; (RANSAC, Fischler and Bolles 1981)"
    )
    assert citations(text) == {
        ("Ali", "2005"), ("Cheng", "2005"), ("Golombek", "1997"), ("Jiang", "2014"),
        ("IAU/IAG", "2000"), ("Loan", "1978"), ("Fischler", "1981"),
    }  # fmt: skip


def test_every_citation_in_the_code_is_in_the_references() -> None:
    listed = citations((ROOT / "docs" / "REFERENCES.md").read_text())
    missing = []
    for package in ("estimation", "sim", "server", "sequences", "bench", "cli", "tests", "web"):
        for path in sorted((ROOT / package).rglob("*")):
            if path.suffix in (".py", ".js", ".html") and path != Path(__file__):
                missing += [
                    f"{path.relative_to(ROOT)}: {author} {year}"
                    for author, year in sorted(citations(path.read_text()) - listed)
                ]
    assert missing == [], "cited but not in docs/REFERENCES.md:\n" + "\n".join(missing)
