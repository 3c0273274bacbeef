"""``roverops validate FILE``: the exit codes, the compiler-format and JSON reports, bad
files and standard input (the language itself: tests/sequences/test_sequences.py)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from cli.validate import NO_ROVER_NOTE
from tests.cli.test_cli import _run as run_cli

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "sequences" / "examples"

_cli = run_cli


def test_cli_valid_file_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    path = str(EXAMPLES / "sol42_drive.seq")
    code, out, err = _cli(capsys, "validate", path)
    assert (code, out) == (0, "")
    assert "0 error(s)" in err
    code, out, _ = _cli(capsys, "validate", path, "--json")
    assert code == 0
    report = json.loads(out)
    assert report == {"file": path, "ok": True, "errors": [], "warnings": [], **NO_ROVER}


NO_ROVER = {"rover": None, "note": NO_ROVER_NOTE}


def test_cli_errors_and_warnings_in_compiler_format(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    path = tmp_path / "bad.seq"
    path.write_text("ARTICULATE_START\nDRIVE_STRAIGHT distance_m=0\nWAIT\n")
    code, out, err = _cli(capsys, "validate", str(path))
    assert code == 1
    assert out.splitlines() == [
        f"{path}:1:1: warning articulate-open the sequence ends in Articulate: "
        "the next sequence's commands will be refused",
        f"{path}:2:27: error bad-value distance_m: must be in (0, 100] m, got 0",
        f"{path}:3:1: error missing-argument WAIT needs duration_s",
    ]
    assert "2 error(s), 1 warning(s)" in err
    code, out, _ = _cli(capsys, "validate", str(path), "--json")
    report = json.loads(out)
    assert code == 1 and report["ok"] is False
    assert [(d["line"], d["column"], d["code"]) for d in report["errors"]] == [
        (2, 27, "bad-value"),
        (3, 1, "missing-argument"),
    ]
    assert report["warnings"][0]["severity"] == "warning"


def test_cli_json_sequence_errors_have_line_0(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    path = tmp_path / "bad.json"
    path.write_text('{"steps": [{"command": "WAIT", "args": {"duration_s": -1}}]}')
    code, out, _ = _cli(capsys, "validate", str(path))
    assert code == 1
    message = "steps[0].args.duration_s: must be in (0, 177550] s, got -1"
    assert out == f"{path}:0:0: error bad-value {message}\n"


@pytest.mark.parametrize("which", ["missing", "directory", "binary"])
def test_cli_bad_file_exits_2_with_one_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, which: str
) -> None:
    path = tmp_path / "nothing.seq"
    if which == "directory":
        path = tmp_path
    elif which == "binary":
        path.write_bytes(b"\xff\xfe\x00WAIT")
    code, out, err = _cli(capsys, "validate", str(path))
    assert code == 2 and out == ""
    assert err.startswith("roverops validate: error: FILE: ") and err.count("\n") == 1


def test_cli_reads_standard_input(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import io

    monkeypatch.setattr(sys, "stdin", io.StringIO("WAIT duration_s=0\n"))
    code, out, _ = _cli(capsys, "validate", "-")
    assert code == 1 and out.startswith("-:1:17: error bad-value duration_s: ")


def test_console_script_missing_file_has_no_traceback(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "cli.main", "validate", str(tmp_path / "absent.seq")],
        capture_output=True,
        text=True,
        check=False,
        cwd=ROOT,
    )
    assert proc.returncode == 2
    assert "no such file" in proc.stderr and "Traceback" not in proc.stderr
    assert proc.stdout == ""
