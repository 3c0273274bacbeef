"""``roverops bench fuzz``: the API fuzzed from its own OpenAPI with schemathesis (issue 13).

The real app under uvicorn on a free port of 127.0.0.1, in a thread of this process, on a
new SQLite database in a temporary directory, its rover clocks not started (the fuzzer
tests the API's contract, not the rover: queued sequences stay queued). schemathesis runs
as a subprocess against ``/openapi.json``, all its phases (examples, coverage, fuzzing,
stateful) in both generation modes (positive and negative), twice: with the operator token
and without one. A middleware in the server counts every response by status, so the 5xx
count is the server's own, not the fuzzer's view of it.

Checks: all of schemathesis's, except those whose assumption this API rightly does not
meet (``EXCLUDED_CHECKS``, each with why).

- ``fuzz_cases``: test cases schemathesis generated over both runs (target >= 5,000).
- ``fuzz_5xx_count``: responses with a 5xx status, counted by the server (target 0).
- ``fuzz_schema_violations``: failures of the schema conformance checks (status code,
  content type, headers, response body) over both runs (target 0).
- ``fuzz_other_check_failures``: failures of the other enabled checks (negative data
  accepted, auth ignored, unsupported method, ...), reported without a target.

The sequence language's own fuzzer (``bench.fuzz_language``, hypothesis mutations of the
example sequences) is merged in by ``language_metrics``.

Output contract: ``bench.result``.
"""

from __future__ import annotations

import contextlib
import json
import logging
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from bench.result import bench_result
from bench.server_process import START_TIMEOUT_S, free_port

# check name -> why this API rightly does not meet its assumption
EXCLUDED_CHECKS: dict[str, str] = {
    "positive_data_acceptance": (
        "a schema-valid body may be a sequence with errors (upload: 422, stored as rejected), "
        "an unknown command, or name an unknown rover (404): the schema cannot say which "
        "sequences are valid, the validator does"
    ),
    "use_after_free": (
        "DELETE /api/sequences/{id} cancels a sequence and keeps its record (GET answers "
        "200 with status cancelled): nothing is freed"
    ),
}
# failure codes (schemathesis.failure_codes) of responses that do not match the schema
SCHEMA_CODES = {"ST103", "ST104", "ST105", "ST106", "ST107", "ST108", "ST109", "ST110", "ST111"}
SERVER_ERROR_CODES = {"ST101", "ST102"}

TARGETS: dict[str, dict[str, float]] = {
    "fuzz_cases": {"ge": 5000},
    "fuzz_5xx_count": {"le": 0},
    "fuzz_schema_violations": {"le": 0},
}
TOKEN = "fuzz-operator-token"


class StatusCounter:
    """ASGI middleware counting the responses by status (and keeping a few 5xx requests
    to report)."""

    def __init__(self, app: Any) -> None:
        self.app = app
        self.statuses: Counter[int] = Counter()
        self.server_errors: list[str] = []

    async def __call__(self, scope: Any, receive: Any, send: Any) -> None:
        async def counting_send(message: Any) -> None:
            if message["type"] == "http.response.start":
                status = int(message["status"])
                self.statuses[status] += 1
                if status >= 500 and len(self.server_errors) < 20:
                    self.server_errors.append(f"{scope['method']} {scope['path']}: {status}")
            await send(message)

        await self.app(scope, receive, counting_send)


@contextlib.contextmanager
def live_server(
    data_dir: Path, token: str = TOKEN, **settings: Any
) -> Iterator[tuple[str, StatusCounter]]:
    """The app under uvicorn on a free port (a thread of this process), clocks not
    started (``settings``: other ``ServerConfig`` fields); its base URL and its status
    counter."""
    import uvicorn

    from server.app import ServerConfig, create_app, data_dir_url

    config = ServerConfig(
        database_url=data_dir_url(data_dir), operator_token=token, start_clocks=False, **settings
    )
    # the fuzzer sends malformed multipart bodies by the hundred: each is a 422, and the
    # multipart parser's log line about it is noise here
    logging.getLogger("python_multipart").setLevel(logging.ERROR)
    counter = StatusCounter(create_app(config))
    port = free_port()
    server = uvicorn.Server(
        uvicorn.Config(counter, host="127.0.0.1", port=port, log_level="critical", lifespan="on")
    )
    thread = threading.Thread(target=server.run, name="fuzz-server", daemon=True)
    thread.start()
    deadline = time.monotonic() + START_TIMEOUT_S
    while not server.started:
        if not thread.is_alive() or time.monotonic() > deadline:
            raise RuntimeError("the server did not start")
        time.sleep(0.05)
    try:
        yield f"http://127.0.0.1:{port}", counter
    finally:
        server.should_exit = True
        thread.join(30.0)


def _schemathesis() -> list[str]:
    found = shutil.which("schemathesis") or str(Path(sys.executable).with_name("schemathesis"))
    return [found]


def run_schemathesis(
    base_url: str, max_examples: int, seed: int, token: str | None, report: Path
) -> dict[str, Any]:
    """One schemathesis run (``max_examples`` per operation and phase) against
    ``base_url``; its JSON report."""
    command = [
        *_schemathesis(), "run", f"{base_url}/openapi.json",
        "--checks", "all", "--exclude-checks", ",".join(EXCLUDED_CHECKS),
        "--max-examples", str(max_examples), "--seed", str(seed),
        "--workers", "1", "--request-timeout", "60", "--no-color",
        "--report", "json", "--report-json-path", str(report),
        "--suppress-health-check", "all", "--warnings", "off",
    ]  # fmt: skip
    if token is not None:
        command += ["--header", f"Authorization: Bearer {token}"]
    # in the report's directory: schemathesis keeps a cache (.schemathesis/) where it runs
    done = subprocess.run(command, capture_output=True, text=True, timeout=3600, cwd=report.parent)
    if not report.exists():
        raise RuntimeError(f"schemathesis wrote no report:\n{done.stdout[-3000:]}{done.stderr}")
    parsed: dict[str, Any] = json.loads(report.read_text())
    parsed["output_tail"] = done.stdout[-4000:]
    return parsed


def fuzz_api(max_examples: int = 200, seed: int = 1) -> dict[str, Any]:
    """Both runs (with and without the token) against one live server; the metrics."""
    cases = schema = other = errors = 0
    failures: list[str] = []
    with tempfile.TemporaryDirectory(prefix="roverops-fuzz-") as tmp:
        with live_server(Path(tmp)) as (base_url, counter):
            for label, token in (("token", TOKEN), ("no_token", None)):
                report = run_schemathesis(
                    base_url, max_examples, seed, token, Path(tmp) / f"{label}.json"
                )
                cases += int(report["test_cases"]["generated"])
                errors += sum(int(e["count"]) for e in report["errors"])
                for failure in report["failures"]:
                    count = int(failure["count"])
                    if failure["code"] in SCHEMA_CODES:
                        schema += count
                    elif failure["code"] not in SERVER_ERROR_CODES:
                        other += count
                    failures.append(
                        f"{label}: {failure['code']} {failure['title']} x{count} "
                        f"{', '.join(failure['operations'])}"
                    )
        statuses = counter.statuses
    return {
        "metrics": {
            "fuzz_cases": cases,
            "fuzz_requests": sum(statuses.values()),
            "fuzz_5xx_count": sum(n for s, n in statuses.items() if s >= 500),
            "fuzz_schema_violations": schema,
            "fuzz_other_check_failures": other,
            "fuzz_errors": errors,
            "fuzz_max_examples": max_examples,
            "fuzz_seed": seed,
        },
        "failures": failures,
        "server_errors": counter.server_errors,
        "statuses": {str(s): n for s, n in sorted(statuses.items())},
    }


def language_metrics(n_inputs: int, seed: int) -> dict[str, Any]:
    """The sequence language fuzzer's metrics (``bench.fuzz_language.fuzz_language``)."""
    from bench.fuzz_language import fuzz_language

    return fuzz_language(n_inputs, seed)


def bench_fuzz(
    max_examples: int = 200, seed: int = 1, language_inputs: int = 2000
) -> dict[str, Any]:
    """The fuzz bench (module docstring); smaller ``max_examples`` make a quick run (the
    targets stay the issue's)."""
    api = fuzz_api(max_examples, seed)
    metrics = dict(api["metrics"])
    # the language fuzzer's figures
    metrics.update(language_metrics(language_inputs, seed))
    result = bench_result("fuzz", metrics, TARGETS)
    # what to look at when a target is missed (beside the contract's keys)
    result["details"] = {
        "excluded_checks": EXCLUDED_CHECKS,
        "failures": api["failures"],
        "server_errors": api["server_errors"],
        "statuses": api["statuses"],
    }
    return result
