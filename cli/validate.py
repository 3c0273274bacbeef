"""``roverops validate FILE``: a sequence file checked as an upload would be, its
diagnostics printed compiler-style (exit 0 without errors, 1 with)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from cli.arguments import database_arguments, env
from sim.errors import InputError


def add_validate(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``validate`` subcommand."""
    check = sub.add_parser(
        "validate",
        help="validate a sequence file (text or JSON); exit 0 if no errors, 1 if errors",
    )
    check.add_argument("file", metavar="FILE", help="sequence file, or - for standard input")
    check.add_argument(
        "--rover",
        help="also predict for this rover (spirit, opportunity): AQF, IMU time, Earth and "
        "sun elevation, time tags; its state from --server, else from the database",
    )
    check.add_argument(
        "--server",
        default=env("SERVER", ""),
        help="a running server's URL (http://localhost:8000): it validates against the "
        "rover's state now, so the answer is the server's (default: read the rover's last "
        "checkpoint from --data-dir/--database-url)",
    )
    check.add_argument(
        "--token",
        default=env("TOKEN", ""),
        help="API token for --server (needed when it reads with --public-read off)",
    )
    database_arguments(check)
    check.add_argument("--json", action="store_true", help="print JSON (one object)")
    check.set_defaults(handler=cmd_validate, printer=print_validation)


NO_ROVER_NOTE = (
    "no rover: time-of-day, AQF, IMU-time and Earth/sun warnings not predicted "
    "(--rover NAME predicts them)"
)


def cmd_validate(args: argparse.Namespace) -> dict[str, Any]:
    """``roverops validate FILE [--rover NAME [--server URL --token T | --data-dir D]]``.

    Without ``--rover`` only what the file alone shows is checked, and the result's note
    says so. With it, the warnings that predict the rover's state (AQF, IMU time, Earth and
    sun elevation, time tags) are made too, from one of two sources:

    - ``--server URL``: the running server validates (``POST /api/sequences/validate?
      rover=NAME``, nothing stored) against the rover's state now, so the answer is the
      server's by construction: the same code, state and moment as an upload's.
    - otherwise the server's database (``--data-dir``/``--database-url``): the rover's last
      checkpoint, validated here (``server.validation.context.stored_rover_site``). No
      server need run; the state is the one a server restarted on that database resumes,
      and validates uploads against (a running server's is at most a second ahead).
    """
    name = args.file
    try:
        text = sys.stdin.read() if name == "-" else Path(name).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError("FILE", f"no such file: {name}") from None
    except IsADirectoryError:
        raise InputError("FILE", f"is a directory: {name}") from None
    except UnicodeDecodeError:
        raise InputError("FILE", f"not UTF-8 text: {name}") from None
    except OSError as error:
        raise InputError("FILE", f"cannot read {name}: {error.strerror}") from None
    if args.rover is None:
        if args.server:
            raise InputError("--server", "needs --rover NAME (the rover to predict for)")
        from sequences.validate import validate

        return {"file": name, **validate(text).as_dict(), "rover": None, "note": NO_ROVER_NOTE}
    if args.server:
        found, source = _validate_on_server(text, args.server, args.rover, args.token)
    else:
        found, source = _validate_on_checkpoint(text, args)
    note = f"predicted for {args.rover} from {source}"
    return {"file": name, **found, "rover": args.rover, "note": note}


def _validate_on_checkpoint(text: str, args: argparse.Namespace) -> tuple[dict[str, Any], str]:
    """Validate ``text`` against the rover's last checkpoint in the server's database."""
    from sequences.validate import validate
    from server.runtime import ROVERS
    from server.storage import Store
    from server.storage.checkpoint import CheckpointFormatError
    from server.validation.context import stored_rover_site

    if args.rover not in ROVERS:
        known = ", ".join(ROVERS)
        raise InputError("--rover", f"unknown rover {args.rover!r}; known: {known}")
    if args.database_url:
        url = args.database_url
    else:
        database = args.data_dir / "roverops.db"
        if not database.is_file():
            raise InputError("--data-dir", f"no server database in {args.data_dir}")
        url = f"sqlite:///{database.resolve()}"
    try:
        store = Store(url)
    except Exception as error:  # any driver's refusal (bad URL, server down): one line
        raise InputError("--database-url", f"cannot open {url}: {error}") from None
    try:
        site = stored_rover_site(store, args.rover)
    except CheckpointFormatError as error:  # written by an older roverops
        raise InputError("--rover", str(error)) from None
    finally:
        store.close()
    if site is None:
        raise InputError("--rover", f"no checkpoint of {args.rover} in {url}: has a server run?")
    context = site.context()
    where = f"its checkpoint ({context.clock(site.start_t_s)}, AQF {site.aqf})"
    return validate(text, context).as_dict(), where


def _validate_on_server(text: str, url: str, rover: str, token: str) -> tuple[dict[str, Any], str]:
    """The server's own validation of ``text`` for ``rover`` (nothing stored)."""
    import urllib.error
    import urllib.parse
    import urllib.request

    base = url.rstrip("/")
    if urllib.parse.urlsplit(base).scheme not in ("http", "https"):
        raise InputError("--server", f"must be an http:// or https:// URL, got {url!r}")
    query = urllib.parse.urlencode({"rover": rover})
    request = urllib.request.Request(
        f"{base}/api/sequences/validate?{query}",
        data=text.encode("utf-8"),
        headers={"content-type": "text/plain; charset=utf-8"},
        method="POST",
    )
    if token:
        request.add_header("authorization", f"Bearer {token}")
    try:
        with urllib.request.urlopen(request, timeout=60) as response:
            body = json.loads(response.read())
    except urllib.error.HTTPError as error:
        raise InputError(*_server_refusal(error, rover)) from None
    except OSError as error:  # URLError, refused, reset, timed out
        reason = getattr(error, "reason", error)
        raise InputError("--server", f"cannot reach {base}: {reason}") from None
    except ValueError:
        raise InputError("--server", f"{base} did not answer JSON: is it roverops?") from None
    found = {
        "ok": bool(body["valid"]),
        "errors": [{**d, "severity": "error"} for d in body["errors"]],
        "warnings": [{**d, "severity": "warning"} for d in body["warnings"]],
    }
    return found, f"the server at {base} (its state now)"


def _server_refusal(error: Any, rover: str) -> tuple[str, str]:
    """The parameter to blame and a one-line message for a server's refusal."""
    try:
        detail = json.loads(error.read()).get("detail")
    except (ValueError, AttributeError, OSError):
        detail = None
    if isinstance(detail, list):  # FastAPI's 422 list: the body was not a sequence
        detail = "; ".join(str(d.get("msg", d)) for d in detail if isinstance(d, dict))
    said = f"{error.code} {detail or error.reason}"
    if error.code in (401, 403):
        return "--token", f"the server refused: {said}"
    if error.code == 404:
        return "--rover", f"the server does not know {rover!r}: {said}"
    if error.code in (413, 422):
        return "FILE", f"the server refused the file: {said}"
    return "--server", f"the server answered {said}"


def print_validation(result: dict[str, Any], as_json: bool) -> None:
    """Compiler-style lines ``FILE:LINE:COL: error|warning CODE message`` on stdout, in
    source order, and a count on stderr (so stdout holds only diagnostics)."""
    if as_json:
        print(json.dumps(result, indent=2))
        return
    from sequences.language import Diagnostic

    found = [Diagnostic(**d) for d in (*result["errors"], *result["warnings"])]
    for diagnostic in sorted(found, key=lambda d: (d.line, d.column)):
        print(diagnostic.format(result["file"]))
    errors, warnings = len(result["errors"]), len(result["warnings"])
    counts = f"{errors} error(s), {warnings} warning(s)"
    print(f"{result['file']}: {counts}; {result['note']}", file=sys.stderr)
