"""``roverops validate --rover NAME`` gives the server's answer (issue 14, item 7).

Without a rover the CLI cannot predict the AQF, the IMU time or the sky, and said nothing
about it: ``gyrocompass_fallback.seq`` had 0 warnings on the CLI and 2 on upload. With
``--rover`` it predicts from the rover's state, taken from a running server (``--server``:
the server validates) or from the server's database (the last checkpoint). A real server
(``tests.server.test_server_restart._start``) is paused, and the same files are validated by its
API, by the CLI through it, and by the CLI from its database: the diagnostics are equal.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from cli.validate import NO_ROVER_NOTE
from server.storage import Store
from tests.cli.test_cli import _run
from tests.server.test_server_restart import AUTH, TOKEN, _free_port, _start, _wait

ROOT = Path(__file__).resolve().parents[2]
FALLBACK = ROOT / "sequences" / "examples" / "gyrocompass_fallback.seq"
# untagged: what it predicts depends on the rover's clock, not only on the file's tags
UNTAGGED = "SEQUENCE now\nDRIVE_STRAIGHT distance_m=2\nHGA_PASS duration_min=15\nSUNFIND\n"


@pytest.fixture(scope="module")
def paused_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, Path]]:
    """A real server on a fresh data directory, spirit's clock paused (and stored so)."""
    data = tmp_path_factory.mktemp("validate-rover")
    port = _free_port()
    proc = _start(data, port, three_d=False)
    url = f"http://127.0.0.1:{port}"
    try:
        _wait(lambda: httpx.get(f"{url}/api/rovers", timeout=5).status_code == 200)
        paused = httpx.post(
            f"{url}/api/rovers/spirit/clock", json={"action": "pause"}, headers=AUTH, timeout=30
        )
        assert paused.status_code == 200 and paused.json()["running"] is False
        yield url, data
    finally:
        proc.terminate()
        proc.wait(timeout=60)


def _server_says(url: str, text: str) -> list[tuple[int, int, str, str]]:
    answer = httpx.post(
        f"{url}/api/sequences/validate",
        params={"rover": "spirit"},
        content=text.encode(),
        headers={"content-type": "text/plain"},
        timeout=60,
    )
    assert answer.status_code == 200, answer.text
    body = answer.json()
    return [(d["line"], d["column"], d["code"], d["message"]) for d in body["warnings"]]


def _cli_says(capsys: pytest.CaptureFixture[str], *argv: str) -> dict[str, Any]:
    code, out, err = _run(capsys, "validate", *argv, "--json")
    assert code == 0, err
    result: dict[str, Any] = json.loads(out)
    return result


def _warnings(result: dict[str, Any]) -> list[tuple[int, int, str, str]]:
    return [(d["line"], d["column"], d["code"], d["message"]) for d in result["warnings"]]


def test_without_a_rover_the_cli_says_it_predicted_nothing(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, err = _run(capsys, "validate", str(FALLBACK))
    assert (code, out) == (0, "")
    assert "0 warning(s)" in err and "no rover" in err and "not predicted" in err
    result = _cli_says(capsys, str(FALLBACK))
    assert result["rover"] is None and result["note"] == NO_ROVER_NOTE


@pytest.mark.parametrize("which", ["fallback", "untagged"])
def test_the_cli_with_a_rover_agrees_with_the_server(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    paused_server: tuple[str, Path],
    which: str,
) -> None:
    url, data = paused_server
    path = FALLBACK
    if which == "untagged":
        path = tmp_path / "untagged.seq"
        path.write_text(UNTAGGED)
    server = _server_says(url, path.read_text())
    through = _cli_says(capsys, str(path), "--rover", "spirit", "--server", url)
    stored = _cli_says(capsys, str(path), "--rover", "spirit", "--data-dir", str(data))
    assert _warnings(through) == server
    assert _warnings(stored) == server
    assert through["rover"] == stored["rover"] == "spirit"
    assert "the server at" in through["note"] and "checkpoint" in stored["note"]
    codes = [code for _, _, code, _ in server]
    if which == "fallback":  # the figure: 2 on upload, 0 on the CLI before
        assert codes == ["drive-not-fine", "drive-not-fine"]
    else:  # a fresh rover's AQF is Unknown
        assert "drive-not-fine" in codes and "hga-not-fine" in codes


def test_the_text_output_says_where_the_rover_state_came_from(
    capsys: pytest.CaptureFixture[str], paused_server: tuple[str, Path]
) -> None:
    url, data = paused_server
    code, out, err = _run(capsys, "validate", str(FALLBACK), "--rover", "spirit", "--server", url)
    assert code == 0 and out.count(" warning drive-not-fine ") == 2
    assert "2 warning(s); predicted for spirit from the server at" in err
    code, _, err = _run(capsys, "validate", str(FALLBACK), "--rover", "spirit", "--data-dir",
                        str(data))  # fmt: skip
    assert code == 0 and "predicted for spirit from its checkpoint (sol " in err
    assert "AQF Unknown" in err


def _refused(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    code, out, err = _run(capsys, "validate", str(FALLBACK), *argv)
    assert (code, out) == (2, ""), err
    assert err.startswith("roverops validate: error: ") and err.count("\n") == 1
    return err


def test_bad_rover_server_token_or_database_is_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, paused_server: tuple[str, Path]
) -> None:
    url, data = paused_server
    assert "unknown rover 'curiosity'" in _refused(capsys, "--rover", "curiosity", "--data-dir",
                                                   str(data))  # fmt: skip
    err = _refused(capsys, "--rover", "curiosity", "--server", url)
    assert "--rover" in err and "404" in err and "curiosity" in err
    err = _refused(capsys, "--rover", "spirit", "--server", url, "--token", "not-a-token-at-all")
    assert "--token" in err and "403" in err
    nobody = f"http://127.0.0.1:{_free_port()}"
    assert "cannot reach" in _refused(capsys, "--rover", "spirit", "--server", nobody)
    assert "http://" in _refused(capsys, "--rover", "spirit", "--server", "localhost:8000")
    assert "needs --rover" in _refused(capsys, "--server", url)
    assert "no server database" in _refused(capsys, "--rover", "spirit", "--data-dir",
                                            str(tmp_path / "absent"))  # fmt: skip
    assert not (tmp_path / "absent").exists()  # looking did not create it
    empty = tmp_path / "empty"
    empty.mkdir()
    Store(f"sqlite:///{empty / 'roverops.db'}").close()  # a database no server ran on
    assert "no checkpoint of spirit" in _refused(capsys, "--rover", "spirit", "--data-dir",
                                                 str(empty))  # fmt: skip


def test_the_console_script_prints_no_traceback_when_the_server_is_unreachable() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "cli.main", "validate", str(FALLBACK), "--rover", "spirit",
         "--server", f"http://127.0.0.1:{_free_port()}", "--token", TOKEN],
        capture_output=True, text=True, check=False, cwd=ROOT,
    )  # fmt: skip
    assert proc.returncode == 2 and "cannot reach" in proc.stderr
    assert "Traceback" not in proc.stderr
