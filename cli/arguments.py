"""The ``roverops`` arguments every subcommand shares: checked types (a bad value is an
argparse error naming the option) and where the server keeps its database.

The options of ``serve`` and the database options default to an environment variable
``ROVEROPS_<NAME>`` where one is set (``env``).
"""

from __future__ import annotations

import argparse
import math
import os
from collections.abc import Callable
from pathlib import Path

from sim.errors import InputError


def finite_float(name: str) -> Callable[[str], float]:
    """An argparse type: a finite number (``name`` is the option, for the message)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text!r}")
        return value

    return parse


def non_negative_int(name: str) -> Callable[[str], int]:
    """An argparse type: an integer >= 0."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be an integer, got {text!r}") from None
        if value < 0:
            raise argparse.ArgumentTypeError(f"{name} must be >= 0, got {value}")
        return value

    return parse


def env(name: str, default: str) -> str:
    """The environment variable ``ROVEROPS_<name>``, else ``default``."""
    return os.environ.get(f"ROVEROPS_{name}", default)


def port_number(text: str) -> int:
    """An argparse type: a TCP port, 1-65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--port must be an integer, got {text!r}") from None
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"--port must be in 1-65535, got {value}")
    return value


def estimator_names(text: str) -> tuple[str, ...]:
    """An argparse type: comma-separated estimator names, ``sapp`` among them."""
    from sim.loop.downlink import ESTIMATORS

    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n not in ESTIMATORS]
    if unknown or "sapp" not in names:
        raise argparse.ArgumentTypeError(
            f"--estimators must list sapp and any of {', '.join(ESTIMATORS)}, got {text!r}"
        )
    return names


def truth_view(text: str) -> str:
    """An argparse type: who sees the simulator's truth, ``everyone`` or ``conductor``
    (``server.access.truth_view``)."""
    from server.access.truth_view import check_truth_view

    try:
        return check_truth_view(text.strip().lower())
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--truth-view must be everyone or conductor, got {text!r}"
        ) from None


def comm_mode(text: str) -> str:
    """An argparse type: a new rover's link, ``instant`` or ``mission`` (``server.comm``)."""
    value = text.strip().lower()
    if value not in ("instant", "mission"):
        raise argparse.ArgumentTypeError(f"--comm must be instant or mission, got {text!r}")
    return value


def dask_scheduler(text: str) -> str:
    """An argparse type: a Dask scheduler's address ``tcp://host:port`` (empty: none)."""
    import re

    value = text.strip()
    found = re.fullmatch(r"tcp://([A-Za-z0-9.\-]+|\[[0-9A-Fa-f:]+\]):(\d{1,5})", value)
    if value and (found is None or not 1 <= int(found[2]) <= 65535):
        raise argparse.ArgumentTypeError(
            f"--dask-scheduler must be tcp://host:port (port 1-65535), got {text!r}"
        )
    return value


def on_off(name: str) -> Callable[[str], bool]:
    """An argparse type: on/off (true/false, 1/0, yes/no)."""

    def parse(text: str) -> bool:
        value = text.strip().lower()
        if value in ("on", "true", "1", "yes"):
            return True
        if value in ("off", "false", "0", "no"):
            return False
        raise argparse.ArgumentTypeError(f"{name} must be on or off, got {text!r}")

    return parse


def database_url(args: argparse.Namespace) -> str:
    """The server database's URL: ``--database-url``, else SQLite in ``--data-dir``."""
    from server.storage import data_dir_url  # not server.app: it imports the whole server

    try:
        return str(args.database_url or data_dir_url(args.data_dir))
    except OSError as exc:
        raise InputError("--data-dir", f"cannot create {args.data_dir}: {exc.strerror}") from None


def database_arguments(parser: argparse.ArgumentParser) -> None:
    """``--data-dir`` and ``--database-url``: where the server keeps its database."""
    parser.add_argument(
        "--data-dir",
        type=Path,
        default=Path(env("DATA_DIR", "data")),
        help="where the embedded SQLite database lives (default ./data)",
    )
    parser.add_argument(
        "--database-url",
        default=env("DATABASE_URL", ""),
        help="any SQLAlchemy URL, e.g. postgresql+psycopg://user@host/db (default: SQLite "
        "in the data directory)",
    )
