"""The ``roverops`` command line: ``serve``, ``ephem``, ``run``, ``validate`` and ``bench``.

Every argument from outside is validated; a bad one ends the command with a one-line
message naming the parameter and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import json
import logging
import math
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from sim.errors import InputError

EXIT_BAD_INPUT = 2


def _finite_float(name: str) -> Callable[[str], float]:
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text!r}")
        return value

    return parse


def _non_negative_int(name: str) -> Callable[[str], int]:
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if value < 0:
            raise argparse.ArgumentTypeError(f"{name} must be >= 0, got {value}")
        return value

    return parse


def _env(name: str, default: str) -> str:
    return os.environ.get(f"ROVEROPS_{name}", default)


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--port must be an integer, got {text!r}") from None
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"--port must be in 1-65535, got {value}")
    return value


def _estimators(text: str) -> tuple[str, ...]:
    from sim.loop.side.kinematic import ESTIMATORS

    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n not in ESTIMATORS]
    if unknown or "sapp" not in names:
        raise argparse.ArgumentTypeError(
            f"--estimators must list sapp and any of {', '.join(ESTIMATORS)}, got {text!r}"
        )
    return names


def _on_off(name: str) -> Callable[[str], bool]:
    def parse(text: str) -> bool:
        value = text.strip().lower()
        if value in ("on", "true", "1", "yes"):
            return True
        if value in ("off", "false", "0", "no"):
            return False
        raise argparse.ArgumentTypeError(f"{name} must be on or off, got {text!r}")

    return parse


def _database_url(args: argparse.Namespace) -> str:
    from server.app import data_dir_url

    try:
        return str(args.database_url or data_dir_url(args.data_dir))
    except OSError as exc:
        raise InputError("--data-dir", f"cannot create {args.data_dir}: {exc.strerror}") from None


def _cmd_serve(args: argparse.Namespace) -> dict[str, Any]:
    import uvicorn

    from server.app import ServerConfig, create_app

    if args.operator_token and len(args.operator_token) < 8:
        raise InputError("--operator-token", "must be at least 8 characters")
    url = _database_url(args)
    config = ServerConfig(
        database_url=url,
        operator_token=args.operator_token or None,
        public_read=args.public_read,
        viewer_3d=not args.no_3d,
        estimators=args.estimators,
    )
    app = create_app(config)
    # A new data directory gets a local admin, its token printed this once (stored hashed:
    # it cannot be shown again; `roverops users token admin` issues another).
    issued = app.state.server.accounts.ensure_local_admin() if not args.operator_token else None
    shown = "localhost" if args.host in ("127.0.0.1", "0.0.0.0") else args.host
    print(f"roverops console: http://{shown}:{args.port}/  (REST API: /docs)", flush=True)
    if config.viewer_3d:
        print(
            f"3D view: http://{shown}:{args.port}/viser/spirit/  (and /viser/opportunity/)",
            flush=True,
        )
    if issued is not None:
        print(
            f"admin token (user {issued.name}, shown once, keep it; sign the console in "
            f"with it): {issued.token}",
            flush=True,
        )
    elif args.operator_token:
        print("bootstrap admin token: the one given by --operator-token", flush=True)
    else:
        print(
            "sign in with your token (new ones: roverops users token NAME --data-dir ...)",
            flush=True,
        )
    print(f"reading without a token: {'on' if args.public_read else 'off'}", flush=True)
    print(f"database: {url}", flush=True)
    # A connection that never closes must not keep an operator's Ctrl-C from stopping it.
    uvicorn.run(
        app, host=args.host, port=args.port, log_level="warning", timeout_graceful_shutdown=10
    )
    return {}


def _cmd_users(args: argparse.Namespace) -> dict[str, Any]:
    """``roverops users add|list|revoke|token|role`` on the server's database (a running
    server sees the change at once: it reads users and tokens on every request)."""
    from server.access.accounts import AccountError, Accounts
    from server.storage import Store

    store = Store(_database_url(args))
    try:
        accounts = Accounts(store)
        if args.action == "list":
            return {"users": accounts.list_users()}
        if args.name is None:
            raise InputError("NAME", f"users {args.action} needs a user name")
        if args.action == "add":
            if args.role is None:
                raise InputError("--role", "users add needs --role viewer|operator|conductor|admin")
            issued = accounts.add_user(args.name, args.role, args.expires_days)
        elif args.action == "token":
            issued = accounts.issue_token(args.name, args.expires_days)
        elif args.action == "role":
            if args.role is None:
                raise InputError("--role", "users role needs --role")
            accounts.set_role(args.name, args.role)
            return {"name": args.name, "role": args.role}
        else:
            return {"name": args.name, "revoked_tokens": accounts.revoke(args.name)}
        return {
            "name": issued.name,
            "role": issued.role,
            "token": issued.token,
            "expires_at": issued.expires_at.isoformat(),
            "note": "the token is shown this once and stored hashed",
        }
    except AccountError as error:
        raise InputError(args.action, str(error)) from None
    finally:
        store.close()


def _print_users(result: dict[str, Any], as_json: bool) -> None:
    if as_json or "users" not in result:
        _print(result, as_json)
        return
    print(f"{'name':<24} {'role':<10} {'live tokens':>11}  created")
    for user in result["users"]:
        print(
            f"{user['name']:<24} {user['role']:<10} {user['live_tokens']:>11}  "
            f"{user['created_at'][:19]}"
        )


def _print(result: dict[str, Any], as_json: bool) -> None:
    if as_json:
        print(json.dumps(result, indent=2))
        return
    for key, value in result.items():
        if isinstance(value, dict):
            print(f"{key}:")
            for sub_key, sub_value in value.items():
                print(f"  {sub_key}: {_fmt(sub_value)}")
        else:
            print(f"{key}: {_fmt(value)}")


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        return f"{round(value, 9) + 0.0:.6g}"  # so 1e-16 of a heading reads as 0, not -0
    if isinstance(value, list):
        return "[" + ", ".join(_fmt(v) for v in value) + "]"
    return str(value)


def _cmd_ephem(args: argparse.Namespace) -> dict[str, Any]:
    from cli.ephem_report import ephem_report

    return ephem_report(args.utc, args.lat_deg, args.lon_west_deg, args.mission)


def _cmd_run(args: argparse.Namespace) -> dict[str, Any]:
    from sim.scenarios.headless import run_scenario

    return run_scenario(
        args.scenario,
        args.seed,
        site=args.site,
        duration_s=args.duration_s,
        distance_m=args.distance_m,
        angle_deg=args.angle_deg,
        estimators=args.estimators,
    )


NO_ROVER_NOTE = (
    "no rover: time-of-day, AQF, IMU-time and Earth/sun warnings not predicted "
    "(--rover NAME predicts them)"
)


def _cmd_validate(args: argparse.Namespace) -> dict[str, Any]:
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


def _print_validation(result: dict[str, Any], as_json: bool) -> None:
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


# Benchmarks of the server, dispatched here: sim (bench.sim) must not import server.
SERVER_BENCHES = {
    "server": "bench.server:bench_server",
    "view3d": "bench.view3d:bench_view3d",
    "restart": "bench.restart:bench_restart",
    "fuzz": "bench.fuzz:bench_fuzz",
}


def _cmd_bench(args: argparse.Namespace) -> dict[str, Any]:
    import importlib

    if args.name in SERVER_BENCHES:
        module, function = SERVER_BENCHES[args.name].split(":")
        bench: Callable[[], dict[str, Any]] = getattr(importlib.import_module(module), function)
        return bench()
    from bench.sim import BENCHES, run_bench

    if args.name not in BENCHES:
        choices = ", ".join([*BENCHES, *SERVER_BENCHES])
        raise InputError("name", f"unknown benchmark {args.name!r}; choose one of {choices}")
    return run_bench(args.name)


def _database_arguments(parser: argparse.ArgumentParser) -> None:
    """``--data-dir`` and ``--database-url``: where the server keeps its database."""
    parser.add_argument(
        "--data-dir",
        type=Path,
        default=Path(_env("DATA_DIR", "data")),
        help="where the embedded SQLite database lives (default ./data)",
    )
    parser.add_argument(
        "--database-url",
        default=_env("DATABASE_URL", ""),
        help="any SQLAlchemy URL, e.g. postgresql+psycopg://user@host/db (default: SQLite "
        "in the data directory)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``roverops``; exposed for tests and documentation."""
    parser = argparse.ArgumentParser(
        prog="roverops",
        description="Ground operations for a simulated Mars Exploration Rover.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    ephem = sub.add_parser(
        "ephem",
        help="Mars time, Sun and Earth directions for a site (Mars24, truth and onboard IVP)",
    )
    ephem.add_argument("--utc", required=True, help="UTC instant, ISO 8601 (2004-01-03T13:46:31)")
    ephem.add_argument(
        "--lat-deg",
        required=True,
        type=_finite_float("--lat-deg"),
        help="planetographic latitude, degrees North",
    )
    ephem.add_argument(
        "--lon-west-deg",
        required=True,
        type=_finite_float("--lon-west-deg"),
        help="West longitude, degrees in [0, 360)",
    )
    ephem.add_argument("--mission", help="spirit or opportunity: also report the sol number")
    ephem.add_argument("--json", action="store_true", help="print JSON")
    ephem.set_defaults(handler=_cmd_ephem)

    run = sub.add_parser("run", help="run a built-in headless scenario and print its summary")
    run.add_argument(
        "--scenario",
        required=True,
        help="rest_1h, drive_100m, turn_360_eq22 or fine_drive_hga (SAPP in the loop)",
    )
    run.add_argument("--seed", type=_non_negative_int("--seed"), default=0, help="random seed")
    run.add_argument("--site", help="override the scenario's site: gusev, meridiani, eq22, flat")
    run.add_argument("--duration-s", type=_finite_float("--duration-s"), help="rest length, s")
    run.add_argument("--distance-m", type=_finite_float("--distance-m"), help="drive length, m")
    run.add_argument("--angle-deg", type=_finite_float("--angle-deg"), help="turn angle, deg")
    run.add_argument(
        "--estimators",
        type=_estimators,
        default=("sapp",),
        help="estimators to run, comma-separated: sapp (always), kinematic_ekf, radio_ekf",
    )
    run.add_argument("--json", action="store_true", help="print JSON")
    run.set_defaults(handler=_cmd_run)

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
        default=_env("SERVER", ""),
        help="a running server's URL (http://localhost:8000): it validates against the "
        "rover's state now, so the answer is the server's (default: read the rover's last "
        "checkpoint from --data-dir/--database-url)",
    )
    check.add_argument(
        "--token",
        default=_env("TOKEN", ""),
        help="API token for --server (needed when it reads with --public-read off)",
    )
    _database_arguments(check)
    check.add_argument("--json", action="store_true", help="print JSON (one object)")
    check.set_defaults(handler=_cmd_validate, printer=_print_validation)

    serve = sub.add_parser(
        "serve",
        help="run the operations server (console, REST, WebSocket); each option also "
        "from an environment variable ROVEROPS_<NAME>",
    )
    serve.add_argument("--host", default=_env("HOST", "127.0.0.1"), help="bind address")
    serve.add_argument(
        "--port", type=_port, default=_port(_env("PORT", "8000")), help="TCP port (1-65535)"
    )
    _database_arguments(serve)
    serve.add_argument(
        "--operator-token",
        default=_env("OPERATOR_TOKEN", ""),
        help="a bootstrap admin token, kept in memory only, for scripts, tests and benches "
        "(default: none; a new data directory gets a local admin whose token is printed once)",
    )
    serve.add_argument(
        "--public-read",
        type=_on_off("--public-read"),
        default=_env("PUBLIC_READ", "on"),  # a string default goes through type= too
        help="on (default): reading needs no token; off: every read, the WebSocket and the "
        "3D view included, needs a viewer token",
    )
    serve.add_argument(
        "--estimators",
        type=_estimators,
        default=_env("ESTIMATORS", "sapp"),  # a string default goes through type= too
        help="estimators on a new rover, comma-separated: sapp (always), kinematic_ekf, radio_ekf",
    )
    serve.add_argument(
        "--no-3d",
        action="store_true",
        default=_env("NO_3D", "") not in ("", "0"),
        help="do not start the viser 3D views (/viser/{rover}/)",
    )
    serve.set_defaults(handler=_cmd_serve, printer=lambda result, as_json: None, json=False)

    users = sub.add_parser(
        "users",
        help="manage users and their API tokens in the server's database",
        description="Users have a role: viewer < operator < conductor < admin (each may do "
        "all that the ones before it may). Tokens are shown once and stored hashed.",
    )
    users.add_argument("action", choices=("add", "list", "revoke", "token", "role"),
                       help="add NAME --role ROLE; list; revoke NAME (all its tokens); "
                       "token NAME (a new token); role NAME --role ROLE")  # fmt: skip
    users.add_argument("name", nargs="?", metavar="NAME", help="the user's name")
    users.add_argument("--role", choices=("viewer", "operator", "conductor", "admin"))
    users.add_argument(
        "--expires-days",
        type=_finite_float("--expires-days"),
        default=90.0,
        help="lifetime of a new token, days (default 90, at most 3650)",
    )
    _database_arguments(users)
    users.add_argument("--json", action="store_true", help="print JSON")
    users.set_defaults(handler=_cmd_users, printer=_print_users)

    bench = sub.add_parser("bench", help="run a benchmark and print its figures")
    bench.add_argument(
        "name", help="benchmark name: sim, sapp, vo, fusion, server, view3d, restart or fuzz"
    )
    bench.add_argument("--json", action="store_true", help="print JSON (one object)")
    bench.set_defaults(handler=_cmd_bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``roverops`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING, format=f"roverops {args.command}: %(message)s")
    try:
        result = args.handler(args)
    except InputError as error:
        print(f"roverops {args.command}: error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    printer: Callable[[dict[str, Any], bool], None] = getattr(args, "printer", _print)
    printer(result, args.json)
    # A benchmark that misses a target still prints its figures, and says so in its status;
    # a sequence with errors prints them: both exit 1.
    return 1 if result.get("ok") is False else 0


if __name__ == "__main__":
    sys.exit(main())
