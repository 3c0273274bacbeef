"""``roverops bench NAME``: run one benchmark of ``bench.registry`` and print its result
object (``bench.result``); ``roverops bench list`` names them with what each measures."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from bench.registry import BENCHES, run_bench
from bench.result import misses, target_text
from cli.output import fmt, print_result

LIST = "list"


def add_bench(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``bench`` subcommand; its help lists the registry."""
    bench = sub.add_parser(
        "bench",
        help="run a benchmark and print its figures",
        description="Run a benchmark and print its figures (exit 1 if a target is missed). "
        "Benchmarks:\n"
        + "\n".join(f"  {name:<8} {entry.description}" for name, entry in BENCHES.items()),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    bench.add_argument("name", help=f"benchmark name: {', '.join(BENCHES)}; or {LIST} to name them")
    bench.add_argument("--json", action="store_true", help="print JSON (one object)")
    bench.set_defaults(handler=cmd_bench, printer=print_bench)


def cmd_bench(args: argparse.Namespace) -> dict[str, Any]:
    """Run the bench named ``args.name``, or list the registry."""
    if args.name == LIST:
        return {name: entry.description for name, entry in BENCHES.items()}
    return run_bench(args.name)


def print_bench(result: dict[str, Any], as_json: bool) -> None:
    """The result (JSON, or a line each with its targets as text), then each missed target
    on stderr, with ``--json`` too: a failing bench says what it missed, and stdout stays
    the one JSON object."""
    if as_json or "targets" not in result:  # bench list: names and descriptions
        print_result(result, as_json)
    else:
        texts = {metric: target_text(target) for metric, target in result["targets"].items()}
        print_result({**result, "targets": texts}, as_json)
    for miss in misses(result) if "targets" in result else []:
        value = "no value" if miss["value"] is None else fmt(miss["value"])
        print(
            f"roverops bench {result['bench']}: missed target: {miss['metric']} = {value}, "
            f"target {target_text(miss['target'])}",
            file=sys.stderr,
        )
