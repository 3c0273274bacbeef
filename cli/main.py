"""The ``roverops`` command line: ``serve``, ``ephem``, ``run``, ``validate``, ``rehearse``,
``users``, ``faults``, ``bench`` and ``web-types``, one module each where they are more than a
call (``cli.serve``, ``cli.validate``, ``cli.rehearse``, ``cli.faults``, ``cli.bench``,
``cli.web_types``), their shared argument types in ``cli.arguments``.

Every argument from outside is validated; a bad one ends the command with a one-line
message naming the parameter and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable, Sequence
from typing import Any

from cli.arguments import estimator_names, finite_float, non_negative_int
from cli.bench import add_bench
from cli.faults import add_faults
from cli.output import print_result
from cli.rehearse import add_rehearse
from cli.run_report import print_run
from cli.serve import add_serve, add_users
from cli.validate import add_validate
from cli.web_types import add_web_types
from sim.errors import InputError

EXIT_BAD_INPUT = 2


def _cmd_ephem(args: argparse.Namespace) -> dict[str, Any]:
    from cli.ephem_report import ephem_report

    return ephem_report(args.utc, args.lat_deg, args.lon_west_deg, args.mission)


def _print_ephem(result: dict[str, Any], as_json: bool) -> None:
    from cli.ephem_report import print_ephem

    print_ephem(result, as_json)


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


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``roverops``; exposed for tests and documentation."""
    parser = argparse.ArgumentParser(
        prog="roverops",
        description="Ground operations for a simulated Mars Exploration Rover.",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    ephem = sub.add_parser(
        "ephem",
        help="Mars time, Sun and Earth directions for a site (Mars24, truth and onboard IVP),"
        " and the one-way light time",
    )
    ephem.add_argument("--utc", required=True, help="UTC instant, ISO 8601 (2004-01-03T13:46:31)")
    ephem.add_argument(
        "--lat-deg",
        required=True,
        type=finite_float("--lat-deg"),
        help="planetographic latitude, degrees North",
    )
    ephem.add_argument(
        "--lon-west-deg",
        required=True,
        type=finite_float("--lon-west-deg"),
        help="West longitude, degrees in [0, 360)",
    )
    ephem.add_argument("--mission", help="spirit or opportunity: also report the sol number")
    ephem.add_argument("--json", action="store_true", help="print JSON")
    ephem.set_defaults(handler=_cmd_ephem, printer=_print_ephem)

    run = sub.add_parser("run", help="run a built-in headless scenario and print its summary")
    run.add_argument(
        "--scenario",
        required=True,
        help="rest_1h, drive_100m, turn_360_eq22 or fine_drive_hga (SAPP in the loop)",
    )
    run.add_argument("--seed", type=non_negative_int("--seed"), default=0, help="random seed")
    run.add_argument(
        "--site",
        help="override the scenario's site: gusev, meridiani, eq22, flat, or a place:"
        " meridiani:endurance_slope, meridiani:purgatory_ripple",
    )
    run.add_argument("--duration-s", type=finite_float("--duration-s"), help="rest length, s")
    run.add_argument("--distance-m", type=finite_float("--distance-m"), help="drive length, m")
    run.add_argument("--angle-deg", type=finite_float("--angle-deg"), help="turn angle, deg")
    run.add_argument(
        "--estimators",
        type=estimator_names,
        default=("sapp",),
        help="estimators to run, comma-separated: sapp (always), kinematic_ekf, radio_ekf",
    )
    run.add_argument("--json", action="store_true", help="print JSON")
    run.set_defaults(handler=_cmd_run, printer=print_run)

    add_validate(sub)
    add_rehearse(sub)
    add_serve(sub)
    add_users(sub)
    add_faults(sub)
    add_bench(sub)
    add_web_types(sub)
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
    printer: Callable[[dict[str, Any], bool], None] = getattr(args, "printer", print_result)
    printer(result, args.json)
    # A benchmark that misses a target still prints its figures, and says so in its status;
    # a sequence with errors prints them: both exit 1.
    return 1 if result.get("ok") is False else 0


if __name__ == "__main__":
    sys.exit(main())
