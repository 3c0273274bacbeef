"""The sequence-language fuzzer (``bench.fuzz_language``): a short deterministic run finds
no crash and no diagnostic without a line; and it does notice both when they happen."""

from __future__ import annotations

from typing import Any

import pytest

import bench.fuzz_language as fuzz
from sequences.language import Diagnostic
from sequences.validate import ValidationResult, validate


def test_two_hundred_mutated_sequences_neither_crash_nor_lose_their_line() -> None:
    figures = fuzz.fuzz_language(200, seed=13)
    assert figures["language_fuzz_inputs"] == 200
    assert figures["language_fuzz_validations"] == 400  # with and without a context
    assert figures["language_fuzz_crashes"] == 0, figures["language_fuzz_failures"]
    assert figures["language_fuzz_diagnostics_without_line"] == 0, figures["language_fuzz_failures"]
    assert figures["language_fuzz_unknown_codes"] == 0


def test_the_same_seed_gives_the_same_inputs(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[list[str]] = [[], []]
    for run in seen:

        def recording(source: Any, context: Any = None, run: list[str] = run) -> Any:
            run.append(repr(source)[:200])
            return validate(source, context)

        monkeypatch.setattr(fuzz, "validate", recording)
        fuzz.fuzz_language(20, seed=5)
    assert seen[0] == seen[1] and len(set(seen[0])) > 5


def test_the_fuzzer_counts_crashes_and_diagnostics_without_a_line(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    def broken(source: Any, context: Any = None) -> ValidationResult:
        if context is None:
            raise RecursionError("deep")
        return ValidationResult(errors=[Diagnostic(0, 0, "error", "syntax", "no place")])

    monkeypatch.setattr(fuzz, "validate", broken)
    figures = fuzz.fuzz_language(10, seed=1)
    assert figures["language_fuzz_crashes"] == 10
    assert figures["language_fuzz_diagnostics_without_line"] == 10
    kinds = {f["kind"] for f in figures["language_fuzz_failures"]}
    assert kinds == {"crash", "no line"}
    assert all(len(f["input"]) <= fuzz.SHOWN_CHARS + 10 for f in figures["language_fuzz_failures"])
