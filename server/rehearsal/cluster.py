"""The Dask cluster a rehearsal campaign runs on: embedded, or a running scheduler.

``RehearsalCluster.local()`` embeds Dask's ``distributed.LocalCluster`` with worker
processes, one per core this process may run on, each with one thread, Numba pinned to one
thread (``NUMBA_NUM_THREADS=1``, set through the Nanny's ``env`` so that it is in the
worker's environment before the run's code imports Numba there: one process with Numba's
default threads uses about 1.35 cores on its own), no dashboard, its logs at WARNING and its
processes niced (``NICE_INCREMENT``) so that a campaign inside the server leaves the CPU to
the live rovers first. ``RehearsalCluster.connect(address)`` is a client on a running
``dask scheduler`` (``tcp://host:port``); its workers are set up by whoever started them.

A run function is named by a reference string, ``"module:function"``
(``DEFAULT_RUN`` is the engine's ``sim.rehearsal.run:run_once``), resolved on the worker:
the server names the engine only by that string and never imports it. Warm-up
(``warm_up``) submits one task per worker that imports the run's module and calls its
``warm_up()`` when it has one, else makes one throwaway run of the campaign's inputs (so
that the Numba kernels are compiled or loaded once per worker, before the runs), and is timed
apart from the runs: ``start_s`` (the cluster's start), ``warmup_s`` (start and warm-up).
"""

from __future__ import annotations

import importlib
import logging
import os
import re
import threading
import time
from collections.abc import Callable
from typing import Any

from distributed import Client, LocalCluster, WorkerPlugin

logger = logging.getLogger(__name__)
_Client: Any = Client  # distributed's API is untyped
_LocalCluster: Any = LocalCluster

DEFAULT_RUN = "sim.rehearsal.run:run_once"
NICE_INCREMENT = 10  # worker processes run at nice +10: the live rovers come first
WORKER_ENV = {"NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
CONNECT_TIMEOUT_S = 10.0
_ADDRESS = re.compile(r"^tcp://(?P<host>[A-Za-z0-9.\-]+|\[[0-9A-Fa-f:]+\]):(?P<port>\d{1,5})$")
_REF = re.compile(r"^[A-Za-z_][\w.]*:[A-Za-z_]\w*$")

RunRef = str | Callable[..., Any]


def validate_address(address: object) -> str:
    """``address`` if it is ``tcp://host:port`` (port 1-65535), else ``ValueError`` naming
    what is wrong."""
    if not isinstance(address, str):
        raise ValueError(f"dask scheduler: must be a string tcp://host:port, got {address!r}")
    match = _ADDRESS.match(address.strip())
    if match is None:
        raise ValueError(f"dask scheduler: must be tcp://host:port, got {address!r}")
    port = int(match["port"])
    if not 1 <= port <= 65535:
        raise ValueError(f"dask scheduler: port must be 1-65535, got {port}")
    return address.strip()


def check_run(run: object) -> RunRef:
    """``run`` if it is a function or a ``"module:function"`` string, else ``ValueError``
    (the string is not imported here)."""
    if callable(run):
        return run
    if isinstance(run, str) and _REF.match(run):
        return run
    raise ValueError(f"run: must be a function or 'module:function', got {run!r}")


def resolve_run(run: RunRef) -> Callable[..., Any]:
    """The run function ``run`` names (``"module:function"``), imported here, or ``run``
    itself when it is already a function."""
    check_run(run)
    if callable(run):
        return run
    module_name, _, attr = run.partition(":")
    return getattr(importlib.import_module(module_name), attr)  # type: ignore[no-any-return]


def usable_cores() -> int:
    """The cores this process may run on (its affinity mask), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def renice_process(increment: int) -> int:
    """Raise the nice value of every thread of this process by ``increment`` (on Linux a
    nice value is per thread; threads started later inherit their creator's) and return the
    process's nice value after."""
    try:
        tids = [int(t) for t in os.listdir("/proc/self/task")]
    except OSError:
        tids = [0]
    target = min(19, os.getpriority(os.PRIO_PROCESS, 0) + increment)
    for tid in tids:
        try:
            if os.getpriority(os.PRIO_PROCESS, tid) < target:
                os.setpriority(os.PRIO_PROCESS, tid, target)
        except OSError:  # a thread that ended meanwhile
            continue
    return os.getpriority(os.PRIO_PROCESS, 0)


class NicePlugin(WorkerPlugin):
    """Renices each worker process as it joins (and any that restarts)."""

    name = "roverops-rehearsal-nice"

    def __init__(self, increment: int = NICE_INCREMENT) -> None:
        self.increment = increment

    def setup(self, worker: Any) -> None:
        renice_process(self.increment)


def _warm_up(run: RunRef, inputs: Any = None) -> float:
    """On a worker: import the run's module and call its ``warm_up()`` if it has one, else,
    given the campaign's ``inputs``, make one throwaway run of them (index 0, seed 0: it
    compiles whatever the runs use); returns the seconds it took."""
    t0 = time.perf_counter()
    fn = resolve_run(run)
    warm = getattr(importlib.import_module(fn.__module__), "warm_up", None)
    if callable(warm):
        warm()
    elif inputs is not None:
        fn(inputs, 0, 0)
    return time.perf_counter() - t0


class RehearsalCluster:
    """A ``distributed.Client`` and, when embedded, the ``LocalCluster`` it owns (module
    docstring). Thread-safe: campaigns submit from request threads."""

    def __init__(self, client: Client, local: LocalCluster | None, start_s: float) -> None:
        # distributed's API is untyped: Any, so that mypy checks the rest
        self.client: Any = client
        self._local: Any = local
        self.start_s = start_s
        self.warmup_s: float | None = None
        self.warmup_task_s: dict[str, float] = {}
        self._warmed: set[str] = set()
        self._lock = threading.Lock()

    @classmethod
    def local(cls, n_workers: int | None = None, *, nice: int = NICE_INCREMENT) -> RehearsalCluster:
        """Start an embedded cluster: ``n_workers`` processes (default: one per usable
        core), one thread each, Numba on one thread, niced by ``nice``."""
        if n_workers is None:
            n_workers = usable_cores()
        if (
            isinstance(n_workers, bool)
            or not isinstance(n_workers, int)
            or not 1 <= n_workers <= 256
        ):
            raise ValueError(f"n_workers: must be an integer 1-256, got {n_workers!r}")
        t0 = time.perf_counter()
        cluster: Any = _LocalCluster(
            n_workers=n_workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            # its health routes on a free local port, not on 8787 (no dashboard either way)
            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
            host="127.0.0.1",
            silence_logs=logging.WARNING,
            env=dict(WORKER_ENV),
        )
        try:
            client: Any = _Client(cluster, set_as_default=False)
            if nice:
                client.register_plugin(NicePlugin(nice))
        except BaseException:
            cluster.close()
            raise
        return cls(client, cluster, time.perf_counter() - t0)

    @classmethod
    def connect(cls, address: str, *, timeout_s: float = CONNECT_TIMEOUT_S) -> RehearsalCluster:
        """A client on the running scheduler at ``address`` (``tcp://host:port``);
        ``ValueError`` for a malformed address, ``ConnectionError`` when none answers
        within ``timeout_s``."""
        address = validate_address(address)
        t0 = time.perf_counter()
        try:
            client: Any = _Client(address, timeout=timeout_s, set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise ConnectionError(
                f"dask scheduler {address}: no answer within {timeout_s:g} s ({exc})"
            ) from exc
        return cls(client, None, time.perf_counter() - t0)

    @property
    def embedded(self) -> bool:
        return self._local is not None

    def workers(self) -> list[str]:
        """The addresses of the workers now connected."""
        return sorted(self.client.scheduler_info(n_workers=-1)["workers"])

    def slots(self) -> int:
        """How many runs can go at once: the workers' threads (at least 1)."""
        return max(1, int(sum(self.client.nthreads().values())))

    def warm_up(
        self, run: RunRef = DEFAULT_RUN, inputs: Any = None, *, timeout_s: float | None = None
    ) -> float:
        """Warm every worker not yet warmed (``_warm_up``: ``inputs`` for a throwaway run when
        the run's module has no ``warm_up()``) and return ``warmup_s``: the cluster's start
        plus the warm-up's wall time, measured once (later calls warm only workers that
        joined since and return the first figure)."""
        with self._lock:
            todo = [w for w in self.workers() if w not in self._warmed]
            if not todo:
                return self.warmup_s if self.warmup_s is not None else self.start_s
            t0 = time.perf_counter()
            futures = [
                self.client.submit(
                    _warm_up, run, inputs, workers=[w], allow_other_workers=False, pure=False,
                    key=f"rehearsal-warmup-{w}-{time.time_ns()}",
                )
                for w in todo
            ]  # fmt: skip
            seconds = [float(f.result(timeout=timeout_s)) for f in futures]
            wall_s = time.perf_counter() - t0
            self.warmup_task_s.update(zip(todo, seconds, strict=True))
            self._warmed.update(todo)
            if self.warmup_s is None:
                self.warmup_s = self.start_s + wall_s
            return self.warmup_s

    def close(self) -> None:
        """Close the client and, when embedded, stop the workers."""
        try:
            self.client.close()
        finally:
            if self._local is not None:
                self._local.close()

    def __enter__(self) -> RehearsalCluster:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
