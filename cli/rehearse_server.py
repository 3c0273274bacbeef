"""``roverops rehearse --server URL``: the campaign asked of a running server and followed
there (``POST /api/rovers/{rover}/rehearsals``, then ``GET .../{id}`` about once a second).
A Ctrl-C cancels it on the server (``POST .../{id}/cancel``)."""

from __future__ import annotations

import argparse
import json
import time
import urllib.error
import urllib.parse
import urllib.request
from typing import Any, Protocol

from sim.errors import InputError

POLL_S = 1.0
FINAL = ("done", "cancelled", "failed")


class ShowsProgress(Protocol):
    def show(self, done: int, eta_s: float | None) -> None: ...
    def end(self) -> None: ...


def _call(base: str, path: str, token: str, body: dict[str, Any] | None = None) -> Any:
    request = urllib.request.Request(
        f"{base}{path}",
        data=None if body is None else json.dumps(body).encode("utf-8"),
        headers={"content-type": "application/json"},
        method="GET" if body is None else "POST",
    )
    if token:
        request.add_header("authorization", f"Bearer {token}")
    try:
        with urllib.request.urlopen(request, timeout=60) as response:
            return json.loads(response.read())
    except urllib.error.HTTPError as error:
        raise InputError(*_refusal(error)) from None
    except OSError as error:  # URLError, refused, reset, timed out
        raise InputError(
            "--server", f"cannot reach {base}: {getattr(error, 'reason', error)}"
        ) from None
    except ValueError:
        raise InputError("--server", f"{base} did not answer JSON: is it roverops?") from None


def _refusal(error: Any) -> tuple[str, str]:
    """The parameter to blame and a one-line message for a server's refusal."""
    try:
        detail = json.loads(error.read()).get("detail")
    except (ValueError, AttributeError, OSError):
        detail = None
    if isinstance(detail, list):  # FastAPI's 422 list
        detail = "; ".join(str(d.get("msg", d)) for d in detail if isinstance(d, dict))
    said = f"{error.code} {detail or error.reason}"
    blame = {400: "FILE", 401: "--token", 403: "--token", 404: "--rover", 413: "FILE"}
    return blame.get(error.code, "--server"), f"the server refused: {said}"


def rehearse_on_server(
    args: argparse.Namespace, text: str, progress: ShowsProgress
) -> dict[str, Any]:
    """The campaign on ``args.server`` (module docstring): its summary and risk table."""
    base = args.server.rstrip("/")
    if urllib.parse.urlsplit(base).scheme not in ("http", "https"):
        raise InputError("--server", f"must be an http:// or https:// URL, got {args.server!r}")
    rover = urllib.parse.quote(args.rover, safe="")
    path = f"/api/rovers/{rover}/rehearsals"
    body = {"sequence_text": text, "runs": args.runs, "seed": args.seed}
    summary = _call(base, path, args.token, body)
    where = f"{path}/{int(summary['id'])}"
    try:
        while summary["state"] not in FINAL:
            progress.show(int(summary["done"]), summary.get("eta_s"))
            time.sleep(POLL_S)
            summary = _call(base, where, args.token)
    except KeyboardInterrupt:
        summary = _call(base, f"{where}/cancel", args.token, {})
    detail = _call(base, where, args.token)
    progress.show(int(detail["done"]), 0.0)
    progress.end()
    return {
        "ok": detail["state"] == "done", "state": detail["state"], "error": detail["error"],
        "runs": detail["runs"], "done": detail["done"], "seed": detail["seed"],
        "warmup_s": detail["warmup_s"], "risk": detail.get("risk"), "id": detail["id"],
        "cluster": f"the server at {base}",
    }  # fmt: skip
