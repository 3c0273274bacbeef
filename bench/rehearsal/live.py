"""The live rovers beside a campaign: ``ws_p99_during_campaign_ms`` of ``roverops bench
rehearsal``.

The real server (``bench.server_process.running_server``: ``roverops serve`` in a
subprocess) runs a campaign started through its REST route (``POST
/api/rovers/spirit/rehearsals``, ``server.rehearsal.api``: the embedded cluster, niced, as
the server starts it on its first campaign) of ``runs`` runs of a 20 m VO drive from
Spirit's last downlink. Once the campaign's first run has finished (the workers are up and
busy), ``bench.server.measure_ws`` opens ``ws_clients`` WebSocket clients on Spirit
articulating at speed 8 for ``ws_window_s``: the p99 of every message's latency is
``ws_p99_during_campaign_ms``. The campaign must still be running when the window closes
(``ws_campaign_runs_during_measure``: the runs that finished from the clients' connection
to the window's end), then it is cancelled.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

from bench.server import ROVER, measure_ws
from bench.server_process import RunningServer, running_server, wait_for

LIVE_SEQUENCE = "SEQUENCE bench_live\nDRIVE_STRAIGHT distance_m={drive_m:g} vo=on\n"
START_TIMEOUT_S = 120.0  # the first downlink, then the cluster's start and first run


def _start_campaign(server: RunningServer, runs: int, drive_m: float) -> int:
    """POST the campaign, retried while Spirit has no downlink yet (409); its id."""
    body = {"sequence_text": LIVE_SEQUENCE.format(drive_m=drive_m), "runs": runs, "seed": 0}
    path = f"/api/rovers/{ROVER}/rehearsals"

    def post() -> Any:
        status, answer = server.request("POST", path, body)
        if status == 409:
            return None
        if status != 202:
            raise RuntimeError(f"POST {path}: HTTP {status}: {answer}")
        return answer

    answer = wait_for(post, START_TIMEOUT_S, "Spirit's first downlink")
    campaign_id: int = answer["id"]
    return campaign_id


def live_metrics(
    runs: int = 40, drive_m: float = 20.0, ws_clients: int = 50, ws_window_s: float = 10.0
) -> dict[str, Any]:
    """The WebSocket figures during a campaign inside the server (module docstring)."""
    with (
        tempfile.TemporaryDirectory(prefix="roverops-bench-") as tmp,
        running_server(Path(tmp)) as server,
    ):
        # frames flow once the clock runs: Spirit's first downlink to start from
        server.ok("POST", f"/api/rovers/{ROVER}/clock", {"speed": 8.0})
        campaign_id = _start_campaign(server, runs, drive_m)
        path = f"/api/rovers/{ROVER}/rehearsals/{campaign_id}"

        def summary() -> dict[str, Any]:
            answer: dict[str, Any] = server.ok("GET", path)
            if answer["state"] in ("failed", "cancelled"):
                raise RuntimeError(f"the campaign ended {answer['state']}: {answer['error']}")
            return answer

        started = time.perf_counter()
        before = wait_for(lambda: (s := summary())["done"] >= 1 and s, START_TIMEOUT_S,
                          "the campaign's first run")  # fmt: skip
        first_run_s = time.perf_counter() - started
        metrics = measure_ws(server, ws_clients, ws_window_s)
        after = summary()
        if after["state"] != "running":
            raise RuntimeError(
                f"the campaign was {after['state']} before the window closed: give it more runs"
            )
        server.ok("POST", f"{path}/cancel")
    return {
        "ws_p99_during_campaign_ms": metrics["ws_p99_latency_ms"],
        "ws_p50_during_campaign_ms": metrics["ws_p50_latency_ms"],
        "ws_clients_during_campaign": metrics["ws_clients"],
        "ws_window_during_campaign_s": ws_window_s,
        "ws_campaign_runs_during_measure": after["done"] - before["done"],
        "ws_campaign_first_run_s": first_run_s,
    }
