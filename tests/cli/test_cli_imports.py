"""The subcommands that need neither the simulator nor the server do not import them
(issue 21: ``roverops users list`` took 6-15 s because it imported the whole server, the
simulator and numba): checked on ``sys.modules`` after the command ran, in a fresh
interpreter, so the invariant holds whatever the machine's speed."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

# Run the command as the console script does, then list what got imported.
_PROBE = """
import json, sys
from cli.main import main
code = main(sys.argv[1:])
print(json.dumps({"code": code, "modules": sorted(sys.modules)}), file=sys.stderr)
"""

# The one module of sim/ every layer's input errors come from: no import of its own.
_SHARED_ERRORS = "sim.errors"
# The definitions of a frame's two records, from which storage makes its columns: plain
# dataclasses (with estimation.events), none of the simulator's machinery.
_RECORDS = ("sim.loop", "sim.loop.records", "sim.loop.downlink", "sim.scoring", "sim.scoring.truth")


def _imported_by(*argv: str) -> list[str]:
    """The modules in ``sys.modules`` after ``roverops ARGV`` ran in a new interpreter."""
    done = subprocess.run(
        [sys.executable, "-c", _PROBE, *argv],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=Path(__file__).resolve().parents[2],
    )
    report = json.loads(done.stderr.strip().splitlines()[-1])
    assert report["code"] == 0, done.stdout + done.stderr
    modules: list[str] = report["modules"]
    return modules


def _heavy(modules: list[str], server_allowed: tuple[str, ...]) -> list[str]:
    """The simulator (but its error type and the records' definitions), any server module
    outside ``server_allowed``,
    and the heavy libraries (numba, OpenCV, the web stack, viser) among ``modules``."""

    def heavy(name: str) -> bool:
        top = name.split(".")[0]
        if top == "sim":
            return name not in ("sim", _SHARED_ERRORS, *_RECORDS)
        if top == "server":
            return name != "server" and not name.startswith(server_allowed)
        return top in ("numba", "cv2", "fastapi", "uvicorn", "viser")

    return [name for name in modules if heavy(name)]


@pytest.mark.parametrize("action", [["list"], ["add", "ada", "--role", "viewer"]])
def test_users_imports_only_the_accounts_and_the_storage(tmp_path: Path, action: list[str]) -> None:
    modules = _imported_by("users", *action, "--data-dir", str(tmp_path))
    assert "server.access.accounts" in modules  # the probe saw the command's own imports
    # storage makes its columns from the channels' definitions (server.channels); the
    # accounts raise the server's domain errors (server.errors: no import of its own)
    allowed = ("server.access", "server.storage", "server.channels", "server.errors")
    assert _heavy(modules, allowed) == []
    assert "server.runtime" not in modules and "server.state" not in modules


def test_bench_list_imports_no_bench() -> None:
    modules = _imported_by("bench", "list")
    assert "bench.registry" in modules
    assert _heavy(modules, ()) == []
    # the list and the output contract, none of the benches themselves
    contract = ("bench.registry", "bench.result")
    assert [m for m in modules if m.startswith("bench.") and m not in contract] == []


def test_validate_without_a_rover_imports_neither_simulator_nor_server() -> None:
    modules = _imported_by("validate", "sequences/examples/fine_drive_hga_sol.seq")
    assert "sequences.validate" in modules
    assert [m for m in modules if m.startswith(("sim.", "server.")) and m != _SHARED_ERRORS] == []
