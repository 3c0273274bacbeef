"""``roverops bench NAME``: run one benchmark of ``bench.registry`` and print its result
object (``bench.result``); ``roverops bench list`` names them with what each measures."""

from __future__ import annotations

import argparse
from typing import Any

from bench.registry import BENCHES, run_bench

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
    bench.set_defaults(handler=cmd_bench)


def cmd_bench(args: argparse.Namespace) -> dict[str, Any]:
    """Run the bench named ``args.name``, or list the registry."""
    if args.name == LIST:
        return {name: entry.description for name, entry in BENCHES.items()}
    return run_bench(args.name)
