"""``roverops serve`` (the operations server) and ``roverops users`` (its accounts)."""

from __future__ import annotations

import argparse
import contextlib
import signal
from types import FrameType
from typing import Any

from cli.arguments import (
    comm_mode,
    dask_scheduler,
    database_arguments,
    database_url,
    env,
    estimator_names,
    finite_float,
    on_off,
    port_number,
    truth_view,
)
from cli.output import print_result
from sim.errors import InputError


def add_serve(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``serve`` subcommand."""
    serve = sub.add_parser(
        "serve",
        help="run the operations server (console, REST, WebSocket); each option also "
        "from an environment variable ROVEROPS_<NAME>",
    )
    serve.add_argument("--host", default=env("HOST", "127.0.0.1"), help="bind address")
    serve.add_argument(
        "--port",
        type=port_number,
        default=port_number(env("PORT", "8000")),
        help="TCP port (1-65535)",
    )
    database_arguments(serve)
    serve.add_argument(
        "--operator-token",
        default=env("OPERATOR_TOKEN", ""),
        help="a bootstrap admin token, kept in memory only, for scripts, tests and benches "
        "(default: none; a new data directory gets a local admin whose token is printed once)",
    )
    serve.add_argument(
        "--public-read",
        type=on_off("--public-read"),
        default=env("PUBLIC_READ", "on"),  # a string default goes through type= too
        help="on (default): reading needs no token; off: every read, the WebSocket and the "
        "3D view included, needs a viewer token",
    )
    serve.add_argument(
        "--truth-view",
        type=truth_view,
        default=env("TRUTH_VIEW", "everyone"),  # a string default goes through type= too
        help="who sees the simulator's truth (true pose, errors, truth channels and alarms, "
        "the 3D view's true rover): everyone (default, for learning alone) or conductor "
        "(the conductor role and above; viewers and operators get the rover's downlink only)",
    )
    serve.add_argument(
        "--comm",
        type=comm_mode,
        default=env("COMM", "instant"),  # a string default goes through type= too
        help="a new rover's link: instant (default: commands and telemetry cross at once) or "
        "mission (across light time: uplink windows, relay passes, data volume; README, "
        "'Operating across light time')",
    )
    serve.add_argument(
        "--estimators",
        type=estimator_names,
        default=env("ESTIMATORS", "sapp"),  # a string default goes through type= too
        help="estimators on a new rover, comma-separated: sapp (always), kinematic_ekf, radio_ekf",
    )
    serve.add_argument(
        "--dask-scheduler",
        type=dask_scheduler,
        default=env("DASK_SCHEDULER", ""),  # a string default goes through type= too
        help="rehearsal campaigns on this running Dask scheduler (tcp://host:port; default: "
        "an embedded cluster, one worker process per core, started on the first campaign)",
    )
    serve.add_argument(
        "--no-3d",
        action="store_true",
        default=env("NO_3D", "") not in ("", "0"),
        help="do not start the viser 3D views (/viser/{rover}/)",
    )
    serve.set_defaults(handler=cmd_serve, printer=lambda result, as_json: None, json=False)


def add_users(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``users`` subcommand."""
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
        type=finite_float("--expires-days"),
        default=90.0,
        help="lifetime of a new token, days (default 90, at most 3650)",
    )
    database_arguments(users)
    users.add_argument("--json", action="store_true", help="print JSON")
    users.set_defaults(handler=cmd_users, printer=print_users)


def cmd_serve(args: argparse.Namespace) -> dict[str, Any]:
    """``roverops serve``: the server under uvicorn until stopped; its URLs printed first."""
    import uvicorn

    from server.app import ServerConfig, create_app

    if args.operator_token and len(args.operator_token) < 8:
        raise InputError("--operator-token", "must be at least 8 characters")
    url = database_url(args)
    config = ServerConfig(
        database_url=url,
        operator_token=args.operator_token or None,
        public_read=args.public_read,
        truth_view=args.truth_view,
        viewer_3d=not args.no_3d,
        estimators=args.estimators,
        comm=args.comm,
        dask_scheduler=args.dask_scheduler or None,
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
    print(f"the simulator's truth shown to: {args.truth_view}", flush=True)
    print(f"a new rover's link: {args.comm}", flush=True)
    print(f"database: {url}", flush=True)
    cluster = args.dask_scheduler or "embedded (started on the first campaign)"
    print(f"rehearsal campaigns on Dask: {cluster}", flush=True)
    # uvicorn shuts down gracefully on SIGINT/SIGTERM, then raises the signal again under
    # the handler it found: with Python's it would die of it (make prints "Terminated") or
    # raise KeyboardInterrupt. This handler turns it into a clean stop, exit status 0.
    for stop in (signal.SIGINT, signal.SIGTERM):
        signal.signal(stop, _stop)
    with contextlib.suppress(StopSignalError):
        # A connection that never closes must not keep an operator's Ctrl-C from stopping it.
        uvicorn.run(
            app, host=args.host, port=args.port, log_level="warning", timeout_graceful_shutdown=10
        )
    print("roverops serve: stopped", flush=True)
    return {}


class StopSignalError(Exception):
    """SIGINT or SIGTERM, raised again by uvicorn after its graceful shutdown."""


def _stop(signum: int, frame: FrameType | None) -> None:
    raise StopSignalError(signal.Signals(signum).name)


def cmd_users(args: argparse.Namespace) -> dict[str, Any]:
    """``roverops users add|list|revoke|token|role`` on the server's database (a running
    server sees the change at once: it reads users and tokens on every request)."""
    from server.access.accounts import AccountError, Accounts
    from server.storage import Store

    store = Store(database_url(args))
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


def print_users(result: dict[str, Any], as_json: bool) -> None:
    """``users list`` as a table; any other answer as ``print_result`` prints it."""
    if as_json or "users" not in result:
        print_result(result, as_json)
        return
    print(f"{'name':<24} {'role':<10} {'live tokens':>11}  created")
    for user in result["users"]:
        print(
            f"{user['name']:<24} {user['role']:<10} {user['live_tokens']:>11}  "
            f"{user['created_at'][:19]}"
        )
