"""``roverops faults inject|list|reveal`` against a running server in training mode: a fault
injected through the CLI is the server's (listed, then revealed), bad options are one line
and exit 2 before any request, and the server's refusals are one line naming the option."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest

from cli.faults import KINDS
from server.app import ServerConfig, data_dir_url
from sim.faults.records import KINDS as RECORD_KINDS
from tests.cli.test_cli import _run
from tests.server.access.test_truth_view import _serve


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, dict[str, str]]]:
    config = ServerConfig(
        database_url=data_dir_url(tmp_path_factory.mktemp("cli-faults")),
        operator_token="cli-faults-bootstrap",
        truth_view="conductor",
        validation_processes=0,
    )
    with _serve(config) as (host, server):
        tokens = {r: server.accounts.add_user(f"{r}9", r).token for r in ("operator", "conductor")}
        yield f"http://{host}", tokens


def _ok(capsys: pytest.CaptureFixture[str], *argv: str) -> Any:
    code, out, err = _run(capsys, "faults", *argv, "--json")
    assert code == 0, err
    return json.loads(out)


def _refused(capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    code, out, err = _run(capsys, "faults", *argv)
    assert (code, out) == (2, ""), err
    assert err.startswith("roverops faults: error: ") and err.count("\n") == 1
    return err


def test_a_fault_injected_listed_and_revealed_through_the_cli(
    capsys: pytest.CaptureFixture[str], served: tuple[str, dict[str, str]]
) -> None:
    url, tokens = served
    where = ("--rover", "spirit", "--server", url, "--token", tokens["conductor"])
    fault = _ok(capsys, "inject", *where, "--kind", "gyro_bias", "--axis", "z",
                "--bias-deg-per-h", "10", "--at-sol", "900", "--at-lmst", "11:30")  # fmt: skip
    assert fault["description"] == "gyro z bias step +10 deg/h"
    assert fault["at"]["sol"] == 900 and fault["at"]["lmst_h"] == pytest.approx(11.5, abs=1e-6)
    listed = _ok(capsys, "list", *where)["faults"]
    assert [(f["fault_id"], f["state"], f["revealed"]) for f in listed] == [
        (fault["fault_id"], "pending", False)
    ]
    revealed = _ok(capsys, "reveal", *where)
    assert revealed["revealed"] == 1 and revealed["faults"][0]["revealed"]


def test_bad_options_and_refusals_are_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str], served: tuple[str, dict[str, str]]
) -> None:
    url, tokens = served
    where = ("--rover", "spirit", "--server", url, "--token", tokens["conductor"])
    assert "--axis: must be one of x, y, z" in _refused(
        capsys, "inject", *where, "--kind", "gyro_bias", "--axis", "w", "--bias-deg-per-h", "1"
    )
    assert "--tau: must be in [0, 10]" in _refused(
        capsys, "inject", *where, "--kind", "pancam_dust", "--tau", "12"
    )
    assert "--bias-ug: is not a parameter of navcam" in _refused(
        capsys, "inject", *where, "--kind", "navcam", "--bias-ug", "3"
    )
    assert "--at-sol and --at-lmst go together" in _refused(
        capsys, "inject", *where, "--kind", "navcam", "--at-sol", "3"
    )
    err = _refused(capsys, "inject", *where, "--kind", "navcam", "--at-utc", "2001-01-01T00:00")
    assert "--at-utc" in err and "before the rover's clock" in err  # the server's 422
    operator = ("--rover", "spirit", "--server", url, "--token", tokens["operator"])
    err = _refused(capsys, "list", *operator)
    assert "--token" in err and "403" in err
    err = _refused(capsys, "list", "--rover", "curiosity", *where[2:])
    assert "--rover" in err and "404" in err
    assert "http://" in _refused(capsys, "list", "--rover", "spirit", "--server", "localhost:1")


def test_the_cli_offers_every_kind_of_fault() -> None:
    assert sorted(KINDS) == sorted(RECORD_KINDS)


def test_a_fault_listed_for_the_terminal_is_one_line() -> None:
    from cli.faults import _fault_line

    fault = {
        "fault_id": 3,
        "description": "sand trap of radius 1.5 m at (3, 0) m",
        "at": {"sol": 100, "lmst_h": 8.5645, "utc": "2004-04-14T15:00:24+00:00", "t_s": 1.0},
        "state": "applied",
        "revealed": True,
    }
    assert _fault_line(fault) == (
        "#3",
        "sand trap of radius 1.5 m at (3, 0) m, sol 100 08:33 LMST: applied, revealed",
    )
