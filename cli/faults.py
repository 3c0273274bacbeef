"""``roverops faults inject|list|reveal``: the test conductor's faults on a running server.

Like ``roverops validate --server``, it talks to a running server's API with a token (the
conductor role's): ``inject`` posts a fault (``POST /api/rovers/{rover}/faults``), ``list``
reads the rover's faults, ``reveal`` reveals them for the debrief. The fault's parameters
are checked here first, by the same records the server checks them with
(``sim.faults.records``), so a bad one is a one-line message naming the option (exit 2)
before any request; a server's refusal is one line too.

    roverops faults inject --rover spirit --kind gyro_bias --axis z --bias-deg-per-h 10 \\
        [--at-utc 2004-04-15T12:00:00 | --at-sol 101 --at-lmst 11:30] \\
        --server http://localhost:8000 --token TOKEN
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from cli.arguments import env, finite_float, non_negative_int
from sim.errors import InputError

# each fault parameter's option (sim.faults.records' field names, with dashes)
PARAMETERS = ("wheel", "mode", "axis", "bias_deg_per_h", "bias_ug", "tau", "x_m", "y_m",
              "radius_m")  # fmt: skip
# sim.faults.records.KINDS (tests/cli/test_cli_faults.py): named here so that building the
# parser imports no simulator (tests/cli/test_cli_imports.py)
KINDS = ("accel_bias", "gyro_bias", "hga_stuck", "navcam", "pancam_dust", "sand_trap", "wheel")


def option(parameter: str) -> str:
    """The command-line option of a fault parameter: ``bias_ug`` -> ``--bias-ug``."""
    return "--" + parameter.replace("_", "-")


def add_faults(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``faults`` subcommand and its actions."""
    faults = sub.add_parser(
        "faults", help="inject, list or reveal a rover's faults on a running server (conductor)"
    )
    actions = faults.add_subparsers(dest="action", required=True, metavar="ACTION")
    inject = actions.add_parser("inject", help="inject a fault (truth side only), now or later")
    listed = actions.add_parser("list", help="the rover's faults: pending, applied, revealed")
    reveal = actions.add_parser("reveal", help="reveal the rover's faults to every reader")
    for action in (inject, listed, reveal):
        action.add_argument("--rover", required=True, help="spirit or opportunity")
        action.add_argument(
            "--server",
            default=env("SERVER", ""),
            help="the running server's URL, e.g. http://localhost:8000",
        )
        action.add_argument("--token", default=env("TOKEN", ""), help="a conductor's API token")
        action.add_argument("--json", action="store_true", help="print JSON")
        action.set_defaults(handler=cmd_faults)
    inject.add_argument("--kind", required=True, choices=KINDS, help="what fails")
    inject.add_argument("--wheel", help="wheel: LF, LM, LR, RF, RM or RR")
    inject.add_argument("--mode", help="wheel: stall or fail (default fail)")
    inject.add_argument("--axis", help="gyro_bias, accel_bias: x, y or z (IMU axes)")
    for name, text in (
        ("bias_deg_per_h", "gyro_bias: the bias step, deg/h"),
        ("bias_ug", "accel_bias: the bias step, micro-g"),
        ("tau", "pancam_dust: the dust's optical depth, 0 to 10"),
        ("x_m", "sand_trap: its centre, m North of the rover's start (mission frame)"),
        ("y_m", "sand_trap: its centre, m East of the rover's start"),
        ("radius_m", "sand_trap: its radius, m"),
    ):
        inject.add_argument(option(name), dest=name, type=finite_float(option(name)), help=text)
    inject.add_argument("--at-utc", help="when, ISO 8601 UTC (default: now)")
    inject.add_argument("--at-sol", type=non_negative_int("--at-sol"), help="when: the sol")
    inject.add_argument("--at-lmst", help="when: LMST on --at-sol, HH:MM or HH:MM:SS")


def lmst_hours(text: str) -> float:
    """``HH:MM`` or ``HH:MM:SS`` as hours; ``InputError`` naming ``--at-lmst`` otherwise."""
    parts = text.split(":")
    try:
        numbers = [int(p) for p in parts]
    except ValueError:
        numbers = []
    if (
        len(numbers) not in (2, 3)
        or not (0 <= numbers[0] < 24)
        or not all(0 <= n < 60 for n in numbers[1:])
    ):
        raise InputError("--at-lmst", f"must be HH:MM or HH:MM:SS on a 24 h clock, got {text!r}")
    return numbers[0] + numbers[1] / 60.0 + (numbers[2] if len(numbers) == 3 else 0) / 3600.0


def fault_body(args: argparse.Namespace) -> dict[str, Any]:
    """The ``POST .../faults`` body of ``inject``'s options, checked by the fault records
    (``InputError`` naming the option of a bad or missing parameter)."""
    from sim.faults.records import fault_from_dict, parameters

    wanted = parameters(args.kind)
    given = {p: getattr(args, p) for p in PARAMETERS if getattr(args, p) is not None}
    stray = [p for p in given if p not in wanted]
    if stray:
        its = ", ".join(option(p) for p in wanted) or "none"
        raise InputError(option(stray[0]), f"is not a parameter of {args.kind} (its: {its})")
    try:
        fault_from_dict({"kind": args.kind, **given})
    except InputError as error:
        raise InputError(option(error.parameter), str(error).split(": ", 1)[1]) from None
    body: dict[str, Any] = {"kind": args.kind, "parameters": given}
    if args.at_utc is not None:
        if args.at_sol is not None or args.at_lmst is not None:
            raise InputError("--at-utc", "give either --at-utc or --at-sol with --at-lmst")
        body["at_utc"] = args.at_utc
    elif (args.at_sol is None) != (args.at_lmst is None):
        raise InputError("--at-sol", "--at-sol and --at-lmst go together")
    elif args.at_sol is not None:
        body |= {"at_sol": args.at_sol, "at_lmst_h": lmst_hours(args.at_lmst)}
    return body


def cmd_faults(args: argparse.Namespace) -> dict[str, Any]:
    """``roverops faults ACTION``: the server's answer (module docstring)."""
    if not args.server:
        raise InputError("--server", "needed: the running server's URL (or ROVEROPS_SERVER)")
    path = f"/api/rovers/{args.rover}/faults"
    if args.action == "inject":
        return _call(args, "POST", path, fault_body(args))
    if args.action == "reveal":
        return _call(args, "POST", f"{path}/reveal", None)
    listed = _call(args, "GET", path, None)
    if getattr(args, "json", False):
        return listed
    return {
        "rover": listed["rover"],
        **{_fault_line(f)[0]: _fault_line(f)[1] for f in listed["faults"]},
    }


def _fault_line(fault: dict[str, Any]) -> tuple[str, str]:
    """One fault as the terminal shows it: ``#id``, then what, when and its state."""
    at = fault["at"]
    state = fault["state"] + (", revealed" if fault["revealed"] else "")
    when = f"sol {at['sol']} {int(at['lmst_h']):02d}:{int(at['lmst_h'] % 1 * 60):02d} LMST"
    return f"#{fault['fault_id']}", f"{fault['description']}, {when}: {state}"


def _call(args: argparse.Namespace, method: str, path: str, body: Any) -> dict[str, Any]:
    """One request to ``--server``; a refusal or an unreachable server is an ``InputError``
    naming the option to blame."""
    import urllib.error
    import urllib.parse
    import urllib.request

    base = args.server.rstrip("/")
    if urllib.parse.urlsplit(base).scheme not in ("http", "https"):
        raise InputError("--server", f"must be an http:// or https:// URL, got {args.server!r}")
    data = None if body is None else json.dumps(body).encode("utf-8")
    request = urllib.request.Request(f"{base}{urllib.parse.quote(path)}", data=data, method=method)
    request.add_header("content-type", "application/json")
    if args.token:
        request.add_header("authorization", f"Bearer {args.token}")
    try:
        with urllib.request.urlopen(request, timeout=60) as response:
            answer: dict[str, Any] = json.loads(response.read())
            return answer
    except urllib.error.HTTPError as error:
        raise InputError(*_refusal(error, args.rover)) from None
    except OSError as error:  # URLError, refused, reset, timed out
        reason = getattr(error, "reason", error)
        raise InputError("--server", f"cannot reach {base}: {reason}") from None
    except ValueError:
        raise InputError("--server", f"{base} did not answer JSON: is it roverops?") from None


def _refusal(error: Any, rover: str) -> tuple[str, str]:
    """The option to blame and a one-line message for a server's refusal."""
    try:
        detail = json.loads(error.read()).get("detail")
    except (ValueError, AttributeError, OSError):
        detail = None
    blame = "--server"
    if isinstance(detail, list):  # a 422: name the first field the server named
        locs = [d.get("loc", []) for d in detail if isinstance(d, dict)]
        if locs and locs[0]:
            field = str(locs[0][-1])
            blame = option("at_lmst" if field == "at_lmst_h" else field)
        detail = "; ".join(str(d.get("msg", d)) for d in detail if isinstance(d, dict))
    said = f"{error.code} {detail or error.reason}"
    if error.code in (401, 403):
        return "--token", f"the server refused: {said}"
    if error.code == 404:
        return "--rover", f"the server does not know {rover!r}: {said}"
    if error.code == 409:
        return "--kind", f"the server refused: {said}"
    return blame, f"the server answered {said}"
