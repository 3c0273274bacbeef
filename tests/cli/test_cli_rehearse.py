"""``roverops rehearse``: a campaign from a server's database on a real Dask cluster (a
``dask scheduler`` and two ``dask worker`` processes on this machine), and every bad
argument refused with a one-line message naming it."""

from __future__ import annotations

import json
import math
import os
import re
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from distributed import Client

from cli.rehearse import print_rehearsal
from server.app import ServerConfig, create_app, data_dir_url
from tests.cli.test_cli import _run
from tests.server.rehearsal.test_gather import play_out

ROOT = Path(__file__).resolve().parents[2]
DASK = Path(sys.executable).parent / "dask"
SEQUENCE = "SEQUENCE short\nDRIVE_STRAIGHT distance_m=0.5\nTURN_IN_PLACE angle_deg=10\n"
START_S = 60.0


@pytest.fixture(scope="module")
def database(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A server's data directory after a short headless run: spirit waited a second."""
    data = Path(tmp_path_factory.mktemp("rehearse-db"))
    app = create_app(ServerConfig(database_url=data_dir_url(data), start_clocks=False,
                                  validation_processes=0))  # fmt: skip
    server = app.state.server
    server.writer.start()
    try:
        wait = "SEQUENCE w\nWAIT duration_s=1\n"
        sequence_id = server.store.add_sequence("spirit", "w", wait, "text", "queued", [], [], [])
        play_out(server.rovers["spirit"], sequence_id, wait)
    finally:
        server.writer.stop()
        server.store.close()
    return data


def _stop(procs: list[subprocess.Popen[str]]) -> None:
    for proc in procs:
        if proc.poll() is None:
            proc.terminate()
    for proc in procs:
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=10)


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, list[str]]]:
    """A real ``dask scheduler`` and two ``dask worker`` processes (one thread each, Numba
    on one thread) importing this repository; always stopped."""
    logs = Path(tmp_path_factory.mktemp("dask-logs"))
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}
    procs: list[subprocess.Popen[str]] = []
    try:
        log = (logs / "scheduler.log").open("w+")
        procs.append(subprocess.Popen(
            [str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard"],
            stdout=log, stderr=subprocess.STDOUT, text=True, cwd=ROOT, env=env,
        ))  # fmt: skip
        deadline = time.monotonic() + START_S
        address = None
        while address is None:
            assert time.monotonic() < deadline, "the scheduler did not start"
            assert procs[0].poll() is None, (logs / "scheduler.log").read_text()
            found = re.search(r"Scheduler at:\s+(tcp://\S+)", (logs / "scheduler.log").read_text())
            address = found[1] if found else None
            time.sleep(0.1)
        for k in range(2):
            out = (logs / f"worker{k}.log").open("w")
            procs.append(subprocess.Popen(
                [str(DASK), "worker", address, "--nthreads", "1", "--nworkers", "1",
                 "--no-dashboard", "--name", f"w{k}"],
                stdout=out, stderr=subprocess.STDOUT, text=True, cwd=ROOT, env=env,
            ))  # fmt: skip
        with Client(address, timeout=START_S, set_as_default=False) as client:
            client.wait_for_workers(2, timeout=START_S)
            workers = sorted(client.scheduler_info()["workers"])
        yield address, workers
    finally:
        _stop(procs)


def test_a_campaign_on_a_real_cluster(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, database: Path,
    scheduler: tuple[str, list[str]],
) -> None:  # fmt: skip
    address, workers = scheduler
    seq = tmp_path / "short.seq"
    seq.write_text(SEQUENCE)
    argv = [str(seq), "--rover", "spirit", "--runs", "4", "--seed", "3",
            "--data-dir", str(database), "--dask-scheduler", address]  # fmt: skip
    code, out, err = _run(capsys, "rehearse", *argv, "--json")
    assert code == 0, err
    result = json.loads(out)
    assert (result["state"], result["done"], result["cluster"]) == ("done", 4, address)
    assert result["workers"] == workers  # both workers ran some
    risk = result["risk"]
    assert risk["runs"] == 4 and [e["line"] for e in risk["lines"]] == [2, 3]
    drive = risk["lines"][0]
    assert drive["command"].startswith("DRIVE_STRAIGHT") and drive["verdict"] in (
        "ok",
        "caution",
        "risk",
    )
    assert math.isclose(sum(drive["status"].values()), 1.0)
    assert len(risk["paths"]) == 4
    assert "4/4 runs" in err  # progress, a line per tenth when stderr is no terminal
    # the text table: a line per sequence line, its verdict, halt and keep-out odds
    print_rehearsal(result, False)
    out, err = capsys.readouterr()
    rows = [line for line in out.splitlines() if re.match(r"\s+\d+\s+(ok|caution|risk)\s", line)]
    assert [int(r.split()[0]) for r in rows] == [2, 3]
    assert rows[0].split()[1] == drive["verdict"]
    assert rows[0].split()[2] == f"{100 * drive['status']['halted']:.1f}"
    assert "4/4 runs, done" in err


def test_bad_arguments_are_refused_with_one_line(
    capsys: pytest.CaptureFixture[str], tmp_path: Path, database: Path,
) -> None:  # fmt: skip
    seq = tmp_path / "s.seq"
    seq.write_text(SEQUENCE)
    db = ["--data-dir", str(database)]
    cases = [
        ([str(tmp_path / "missing.seq"), "--rover", "spirit", *db], "no such file"),
        ([str(seq), "--rover", "curiosity", *db], "unknown rover 'curiosity'"),
        ([str(seq), "--rover", "opportunity", *db], "no downlink record of opportunity"),
        ([str(seq), "--rover", "spirit", "--data-dir", str(tmp_path)], "no server database"),
        ([str(seq), "--rover", "spirit", *db, "--dask-scheduler", "localhost:8786"],
         "--dask-scheduler must be tcp://host:port"),
        ([str(seq), "--rover", "spirit", *db, "--runs", "0"], "--runs must be in 1-1000"),
        ([str(seq), "--rover", "spirit", *db, "--seed", str(2**63)], "--seed must be at most"),
        ([str(seq), "--rover", "spirit", "--server", "ftp://x"], "http:// or https://"),
    ]  # fmt: skip
    for argv, words in cases:
        code, _, err = _run(capsys, "rehearse", *argv)
        assert code == 2, (argv, err)
        assert words in err and "Traceback" not in err, (argv, err)
    bad = tmp_path / "bad.seq"
    bad.write_text("SEQUENCE bad\nDRIVE_STRAIGHT distance_m=oops\n")
    code, _, err = _run(capsys, "rehearse", str(bad), "--rover", "spirit", *db)
    assert code == 2 and "line 2:" in err, err
    with socket.socket() as s:  # a port no scheduler listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    code, _, err = _run(capsys, "rehearse", str(seq), "--rover", "spirit", *db,
                        "--dask-scheduler", f"tcp://127.0.0.1:{port}")  # fmt: skip
    assert code == 2 and "cannot reach" in err, err


def test_serve_takes_a_dask_scheduler(capsys: pytest.CaptureFixture[str]) -> None:
    from cli.main import build_parser

    parsed = build_parser().parse_args(["serve", "--dask-scheduler", "tcp://10.0.0.5:8786"])
    assert parsed.dask_scheduler == "tcp://10.0.0.5:8786"
    assert build_parser().parse_args(["serve"]).dask_scheduler in ("", os.environ.get(
        "ROVEROPS_DASK_SCHEDULER", ""))  # fmt: skip
    for bad in ("8786", "tcp://host", "tcp://host:0", "tcp://host:99999", "http://host:1"):
        code, _, err = _run(capsys, "serve", "--dask-scheduler", bad)
        assert code == 2 and "--dask-scheduler must be tcp://host:port" in err, (bad, err)
