"""``roverops rehearse FILE --rover NAME --runs N``: a rehearsal campaign of a sequence file
(issue 25), its risk table printed (a line per sequence line) or as JSON.

- ``--server URL``: the running server rehearses (``POST /api/rovers/{rover}/rehearsals``,
  then its progress polled about once a second until the campaign is over); the answer is
  the server's, stored there.
- otherwise the campaign runs here, from the server's database (``--db`` /
  ``--database-url`` / ``--data-dir``, as ``roverops serve`` finds it): the rover's last
  stored downlink record, its stored events and the ground map of its stored pairs
  (``server.rehearsal.gather.stored_inputs``), on an embedded Dask ``LocalCluster`` (one
  worker process per core) or on ``--dask-scheduler tcp://host:port``
  (``ROVEROPS_DASK_SCHEDULER``).

Progress goes to stderr: a bar with the runs done and the ETA when stderr is a terminal,
else a line each tenth of the runs. A campaign that fails or is interrupted exits 1.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

from cli.arguments import dask_scheduler, database_arguments, env, non_negative_int
from sim.errors import InputError

POLL_S = 1.0  # how often a server's campaign is asked for its progress
BAR_CELLS = 30
MAX_SEED = 2**63 - 1


def _runs(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--runs must be an integer, got {text!r}") from None
    if not 1 <= value <= 1000:
        raise argparse.ArgumentTypeError(f"--runs must be in 1-1000, got {value}")
    return value


def _seed(text: str) -> int:
    value = non_negative_int("--seed")(text)
    if value > MAX_SEED:
        raise argparse.ArgumentTypeError(f"--seed must be at most 2**63-1, got {value}")
    return value


def add_rehearse(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """The ``rehearse`` subcommand."""
    rehearse = sub.add_parser(
        "rehearse",
        help="rehearse a sequence file many times on sampled worlds (Dask) and print its "
        "risk table; from a running server (--server) or the server's database",
    )
    rehearse.add_argument("file", metavar="FILE", help="sequence file (text or JSON)")
    rehearse.add_argument("--rover", required=True, help="spirit or opportunity")
    rehearse.add_argument("--runs", type=_runs, default=100, help="runs, 1-1000 (default 100)")
    rehearse.add_argument("--seed", type=_seed, default=0, help="campaign seed (default 0)")
    rehearse.add_argument(
        "--server",
        default=env("SERVER", ""),
        help="a running server's URL (http://localhost:8000): it runs and stores the campaign",
    )
    rehearse.add_argument("--token", default=env("TOKEN", ""), help="an operator's API token")
    rehearse.add_argument(
        "--db", default="", help="the server's database URL (default: --database-url / --data-dir)"
    )
    database_arguments(rehearse)
    rehearse.add_argument(
        "--dask-scheduler",
        type=dask_scheduler,
        default=env("DASK_SCHEDULER", ""),  # a string default goes through type= too
        help="run on this Dask scheduler (tcp://host:port; default: an embedded cluster)",
    )
    rehearse.add_argument("--json", action="store_true", help="print JSON (one object)")
    rehearse.set_defaults(handler=cmd_rehearse, printer=print_rehearsal)


def _read(name: str) -> str:
    try:
        return Path(name).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError("FILE", f"no such file: {name}") from None
    except IsADirectoryError:
        raise InputError("FILE", f"is a directory: {name}") from None
    except UnicodeDecodeError:
        raise InputError("FILE", f"not UTF-8 text: {name}") from None
    except OSError as error:
        raise InputError("FILE", f"cannot read {name}: {error.strerror}") from None


class Progress:
    """Progress on stderr (module docstring)."""

    def __init__(self, total: int) -> None:
        self.total = total
        self.tty = sys.stderr.isatty()
        self.decile = -1

    def show(self, done: int, eta_s: float | None) -> None:
        eta = "?" if eta_s is None else _duration(eta_s)
        if self.tty:
            cells = int(BAR_CELLS * done / self.total)
            bar = "#" * cells + "-" * (BAR_CELLS - cells)
            print(f"\r[{bar}] {done}/{self.total} runs, ETA {eta}  ", end="", file=sys.stderr)
        elif (decile := 10 * done // self.total) > self.decile:
            self.decile = decile
            print(f"{done}/{self.total} runs, ETA {eta}", file=sys.stderr, flush=True)

    def end(self) -> None:
        if self.tty:
            print(file=sys.stderr)


def _duration(seconds: float) -> str:
    seconds = max(0.0, seconds)
    return (
        f"{int(seconds // 60)} min {int(seconds % 60)} s" if seconds >= 60 else f"{seconds:.0f} s"
    )


def cmd_rehearse(args: argparse.Namespace) -> dict[str, Any]:
    """``roverops rehearse`` (module docstring)."""
    text = _read(args.file)
    if args.server:
        from cli.rehearse_server import rehearse_on_server

        found = rehearse_on_server(args, text, Progress(args.runs))
    else:
        found = _rehearse_here(args, text)
    return {"file": args.file, "rover": args.rover, **found}


def _store(args: argparse.Namespace) -> Any:
    from server.storage import Store

    if args.db or args.database_url:
        url = args.db or args.database_url
        option = "--db" if args.db else "--database-url"
    else:
        database = args.data_dir / "roverops.db"
        if not database.is_file():
            raise InputError("--data-dir", f"no server database in {args.data_dir}")
        url, option = f"sqlite:///{database.resolve()}", "--data-dir"
    try:
        return Store(url)
    except Exception as error:  # any driver's refusal (bad URL, server down): one line
        raise InputError(option, f"cannot open {url}: {error}") from None


def _rehearse_here(args: argparse.Namespace, text: str) -> dict[str, Any]:
    """The campaign on this machine's cluster (or ``--dask-scheduler``'s), from the
    database."""
    from sequences.validate import validate
    from server.rehearsal.gather import NoReportError, stored_inputs
    from server.rovers import ROVERS

    if args.rover not in ROVERS:
        raise InputError("--rover", f"unknown rover {args.rover!r}; known: {', '.join(ROVERS)}")
    result = validate(text)
    if result.errors:
        first = "; ".join(f"line {d.line}: {d.message}" for d in result.errors[:3])
        raise InputError("FILE", f"{len(result.errors)} error(s): {first}")
    store = _store(args)
    try:
        inputs = stored_inputs(store, args.rover, text)
    except NoReportError as error:
        raise InputError("--rover", str(error)) from None
    finally:
        store.close()
    return run_campaign(inputs, args.runs, args.seed, args.dask_scheduler)


def run_campaign(inputs: Any, runs: int, seed: int, scheduler: str) -> dict[str, Any]:
    """A campaign of ``inputs`` on an embedded cluster or ``scheduler``'s, with progress on
    stderr; its summary and risk table."""
    from server.rehearsal.campaign import Campaign
    from server.rehearsal.cluster import RehearsalCluster
    from server.rehearsal.service import campaign_risk

    started = time.monotonic()
    try:
        cluster = RehearsalCluster.connect(scheduler) if scheduler else RehearsalCluster.local()
    except (ValueError, ConnectionError, OSError, TimeoutError) as error:
        raise InputError("--dask-scheduler", f"cannot reach {scheduler}: {error}") from None
    progress = Progress(runs)
    try:
        warmup_s = cluster.warm_up()
        campaign = Campaign(cluster, inputs, runs, seed)
        try:
            while not campaign.wait(0.25):
                now = campaign.progress()
                progress.show(now.done, now.eta_s)
        except KeyboardInterrupt:
            campaign.cancel()
        now = campaign.progress()
        progress.show(now.done, now.eta_s)
        progress.end()
        outcomes = campaign.outcomes()
        risk = campaign_risk(inputs, outcomes) if outcomes else None
    finally:
        cluster.close()
    return {
        "ok": now.state == "done", "state": now.state, "error": now.error, "runs": runs,
        "done": now.done, "seed": seed, "warmup_s": warmup_s,
        "wall_s": time.monotonic() - started, "risk": risk,
        "cluster": scheduler or "embedded",
    }  # fmt: skip


def _p(value: Any) -> str:
    return "-" if value is None else f"{100.0 * value:.1f} %"


def risk_lines(risk: dict[str, Any]) -> list[str]:
    """The risk table as text: a line per sequence line (verdict, halt and keep-out
    probabilities, the end pose's 95 % ellipse, tilt p95)."""
    out = [f"{'line':>4}  {'verdict':<7}  {'halt':>7}  {'keep-out':>8}  "
           f"{'end 95 % ellipse (N, E; a x b m @ deg)':<40}  {'tilt p95':>8}  command"]  # fmt: skip
    for entry in risk["lines"]:
        status = entry.get("status") or {}
        keepouts = entry.get("keepouts") or {}
        end = entry.get("end_true")
        if end:
            e = end["ellipse_95"]
            n, east = end["mean_m"]
            pose = f"{n:.2f}, {east:.2f}; {e['a_m']:.2f} x {e['b_m']:.2f} @ {e['angle_deg']:.0f}"
        else:
            pose = "-"
        tilt = (entry.get("max_tilt_deg") or {}).get("p95")
        tilt_text = "-" if tilt is None else f"{tilt:.1f} deg"
        out.append(
            f"{entry['line']:>4}  {entry['verdict']:<7}  {_p(status.get('halted')):>7}  "
            f"{_p(max(keepouts.values()) if keepouts else 0.0):>8}  {pose:<40}  "
            f"{tilt_text:>8}  {entry['command']}"
        )
        out += [f"{'':>6}{why}" for why in entry.get("why") or []]
    return out


def print_rehearsal(result: dict[str, Any], as_json: bool) -> None:
    """The risk table (text or JSON) on stdout; the campaign's state on stderr."""
    if as_json:
        print(json.dumps(result, indent=2))
        return
    if result.get("risk"):
        print("\n".join(risk_lines(result["risk"])))
    said = f"{result['done']}/{result['runs']} runs, {result['state']}"
    if result.get("warmup_s") is not None and math.isfinite(result["warmup_s"]):
        said += f"; workers' start and warm-up {result['warmup_s']:.1f} s"
    if result.get("error"):
        said += f": {result['error']}"
    print(f"{result['file']}: rehearsed on {result['rover']}: {said}", file=sys.stderr)
