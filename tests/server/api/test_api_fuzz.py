"""The API fuzzed from its own OpenAPI (issue 13): a short schemathesis run against the live
server (uvicorn on a free port, a temporary SQLite database), with the operator token and
without, all checks but the two the API rightly does not meet (``EXCLUDED_CHECKS``, each with
why). No 5xx, no response outside the schema, no other check failing. ``roverops bench fuzz``
runs the long one."""

from __future__ import annotations

from typing import Any

import pytest

from bench.fuzz import EXCLUDED_CHECKS, TARGETS, bench_fuzz
from cli.main import main


@pytest.fixture(scope="module")
def short_run() -> dict[str, Any]:
    return bench_fuzz(max_examples=5, seed=1, language_inputs=20)


def test_no_5xx_and_no_response_outside_the_schema(short_run: dict[str, Any]) -> None:
    m = short_run["metrics"]
    details = short_run["details"]
    assert m["fuzz_cases"] > 500 and m["fuzz_requests"] >= m["fuzz_cases"]
    assert m["fuzz_5xx_count"] == 0, details["server_errors"]
    assert m["fuzz_schema_violations"] == 0, details["failures"]
    assert m["fuzz_other_check_failures"] == 0 and m["fuzz_errors"] == 0, details["failures"]
    # both runs reached the server: with the token (2xx) and without it (401)
    assert int(details["statuses"]["200"]) > 0 and int(details["statuses"]["401"]) > 0


def test_the_output_contract(short_run: dict[str, Any]) -> None:
    assert {"bench", "metrics", "targets", "ok"} <= set(short_run)
    assert short_run["bench"] == "fuzz" and short_run["targets"] == TARGETS
    assert set(TARGETS) == {"fuzz_cases", "fuzz_5xx_count", "fuzz_schema_violations"}
    assert short_run["ok"] is False  # a short run is not the 5,000 cases of the target
    assert set(short_run["details"]["excluded_checks"]) == set(EXCLUDED_CHECKS)


def test_bench_fuzz_is_a_roverops_bench(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "warp", "--json"]) == 2
    assert "fuzz" in capsys.readouterr().err
