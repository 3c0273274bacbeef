"""A rehearsal campaign: N runs of a sequence on a Dask cluster, their progress, cancel.

``Campaign(cluster, inputs, runs, seed)`` starts a thread of its own (``start`` returns at
once): it warms the workers not yet warmed (``RehearsalCluster.warm_up``; the campaign is
``queued`` meanwhile), scatters the ``RehearsalInputs`` to every worker once
(``client.scatter(..., broadcast=True)``: each run gets the future, not a pickled copy) and
submits one task per run, keyed by the campaign's id and the run's index. A run is
``run(inputs, run_index, campaign_seed) -> RunOutcome`` (default the engine's ``run_once``,
``cluster.DEFAULT_RUN``: named by a string and resolved on the worker); it draws
everything it samples from its index and the campaign's seed, so the outcomes do not depend
on the number of workers or on the order runs finish in.

The same thread then gathers the runs as they finish. ``progress()`` gives the runs done,
the total, an ETA and the state (``queued`` until the runs are submitted, ``running``,
``done``, ``cancelled``, ``failed``). A run that raises fails the campaign with its error (the other
runs are cancelled); ``cancel()`` cancels what has not finished and keeps what has;
``outcomes()`` are the finished runs sorted by index. Every method may be called from any
thread; ``on_progress`` callbacks run on the campaign's thread, when the runs are
submitted, after each finished run and at the end.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from distributed import Future, as_completed, get_worker

from server.rehearsal.cluster import DEFAULT_RUN, RehearsalCluster, RunRef, check_run, resolve_run
from sim.rehearsal.inputs import RehearsalInputs
from sim.rehearsal.outcome import RunOutcome

logger = logging.getLogger(__name__)
_as_completed: Any = as_completed  # distributed's API is untyped

MAX_RUNS = 1000
MAX_SEED = 2**63 - 1
STATES = ("queued", "running", "done", "cancelled", "failed")
FINAL_STATES = frozenset({"done", "cancelled", "failed"})


@dataclass(frozen=True)
class Progress:
    """Where a campaign stands: ``done`` of ``total`` runs, ``eta_s`` (None until a run has
    finished, 0 once over), ``state`` and ``error`` (the failing run's error)."""

    done: int
    total: int
    eta_s: float | None
    state: str
    error: str | None = None

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _run_task(run: RunRef, inputs: RehearsalInputs, run_index: int, seed: int) -> RunOutcome:
    """On a worker: one run, with its wall time and the worker's address recorded."""
    t0 = time.perf_counter()
    outcome = resolve_run(run)(inputs, run_index, seed)
    if not isinstance(outcome, RunOutcome):
        raise TypeError(f"run {run_index}: the run function returned {type(outcome).__name__}")
    try:
        worker = get_worker().address
    except ValueError:  # not on a worker
        worker = ""
    return dataclasses.replace(outcome, wall_s=time.perf_counter() - t0, worker=worker)


def _check_int(name: str, value: object, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ValueError(f"{name}: must be an integer {lo}-{hi}, got {value!r}")
    return value


class Campaign:
    """One campaign (module docstring). ``runs`` 1-``MAX_RUNS``, ``seed`` 0-2**63-1; ``run``
    a function or a ``"module:function"`` the workers can import; ``start=False`` leaves it
    ``queued`` until ``start()``; ``warm=False`` skips the workers' warm-up."""

    def __init__(
        self,
        cluster: RehearsalCluster,
        inputs: RehearsalInputs,
        runs: int,
        seed: int = 0,
        run: RunRef = DEFAULT_RUN,
        *,
        campaign_id: str | None = None,
        start: bool = True,
        warm: bool = True,
    ) -> None:
        if not isinstance(inputs, RehearsalInputs):
            raise ValueError(f"inputs: must be RehearsalInputs, got {type(inputs).__name__}")
        self.total = _check_int("runs", runs, 1, MAX_RUNS)
        self.seed = _check_int("seed", seed, 0, MAX_SEED)
        check_run(run)
        self.cluster = cluster
        self.inputs = inputs
        self.run = run
        self.warm = warm
        self.id = campaign_id or uuid.uuid4().hex[:12]
        self._lock = threading.Lock()
        self._finished = threading.Event()
        self._state = "queued"
        self._error: str | None = None
        self._outcomes: dict[int, RunOutcome] = {}
        self._futures: list[Future[RunOutcome]] = []
        self._inputs_future: Future[RehearsalInputs] | None = None
        self._slots = 1
        self._callbacks: list[Callable[[Progress], None]] = []
        self.started_at_s: float | None = None  # time.monotonic() of start()
        self.finished_at_s: float | None = None
        if start:
            self.start()

    # --- control -------------------------------------------------------------------
    def start(self) -> None:
        """Launch the campaign on its own thread (once; later calls do nothing): warm the
        workers not yet warmed (``RehearsalCluster.warm_up``, while ``queued``), scatter
        the inputs, submit the runs (``running``), then gather them as they finish."""
        with self._lock:
            if self._state != "queued" or self.started_at_s is not None:
                return
            self.started_at_s = time.monotonic()
        threading.Thread(target=self._launch, name=f"rehearsal-{self.id}", daemon=True).start()

    def cancel(self) -> Progress:
        """Cancel the runs not finished; those finished are kept. No effect once over."""
        with self._lock:
            if self._state in FINAL_STATES:
                return self._progress_locked()
            futures = list(self._futures)
        self._finish("cancelled", None)  # first: the watcher then takes no cancelled run as lost
        if futures:
            self.cluster.client.cancel(futures)
        return self.progress()

    def on_progress(self, callback: Callable[[Progress], None]) -> None:
        """Call ``callback(progress)`` when the runs are submitted, after each finished run and
        once at the end (on the campaign's thread: keep it short; its exceptions are logged,
        not raised)."""
        with self._lock:
            self._callbacks.append(callback)

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the campaign is over (done, cancelled or failed), at most ``timeout``
        seconds; True if it is over."""
        return self._finished.wait(timeout)

    # --- readouts -------------------------------------------------------------------
    @property
    def state(self) -> str:
        with self._lock:
            return self._state

    @property
    def error(self) -> str | None:
        with self._lock:
            return self._error

    def progress(self) -> Progress:
        with self._lock:
            return self._progress_locked()

    def outcomes(self) -> list[RunOutcome]:
        """The finished runs' outcomes, sorted by run index."""
        with self._lock:
            return [self._outcomes[i] for i in sorted(self._outcomes)]

    # --- inside ---------------------------------------------------------------------
    def _progress_locked(self) -> Progress:
        done = len(self._outcomes)
        eta_s: float | None
        if self._state in FINAL_STATES:
            eta_s = 0.0
        elif done == 0:
            eta_s = None
        else:
            # the runs left, spread over the slots, at the finished runs' mean wall time
            mean_wall_s = sum(o.wall_s for o in self._outcomes.values()) / done
            left = self.total - done
            eta_s = -(-left // max(1, min(self._slots, left))) * mean_wall_s
        return Progress(done, self.total, eta_s, self._state, self._error)

    def _launch(self) -> None:
        client: Any = self.cluster.client
        try:
            if self.warm:
                self.cluster.warm_up(self.run, self.inputs)
            if self.state in FINAL_STATES:  # cancelled while warming
                return
            self._slots = self.cluster.slots()
            inputs_future = client.scatter(self.inputs, broadcast=True, hash=False)
            futures = [
                client.submit(
                    _run_task, self.run, inputs_future, i, self.seed,
                    key=f"rehearsal-{self.id}-{i}", pure=False, priority=-i,
                )
                for i in range(self.total)
            ]  # fmt: skip
        except Exception as exc:  # the cluster is gone, refuses the work, or warm-up failed
            self._finish("failed", f"starting the runs: {type(exc).__name__}: {exc}")
            return
        with self._lock:
            cancelled = self._state in FINAL_STATES
            if not cancelled:
                self._state = "running"
                self._inputs_future = inputs_future
                self._futures = futures
        if cancelled:  # cancel() came while submitting
            client.cancel(futures)
            return
        self._notify()
        self._watch(futures)

    def _watch(self, futures: list[Future[RunOutcome]]) -> None:
        try:
            for future in _as_completed(futures, loop=self.cluster.client.loop):
                if self.state in FINAL_STATES:
                    break
                status = future.status
                if status == "finished":
                    outcome = future.result()
                    with self._lock:
                        if self._state not in FINAL_STATES:
                            self._outcomes[outcome.run_index] = outcome
                    self._notify()
                elif status == "error":
                    exc = future.exception()
                    index = int(str(future.key).rsplit("-", 1)[1])
                    self.cluster.client.cancel(futures)
                    self._finish("failed", f"run {index}: {type(exc).__name__}: {exc}")
                    return
                # a cancelled future: cancel() or the cluster; cancel() sets the state
            with self._lock:
                complete = len(self._outcomes) == self.total
            if complete:
                self._finish("done", None)
            elif self.state not in FINAL_STATES:
                self._finish("failed", "the cluster lost runs (cancelled outside the campaign)")
        except Exception as exc:  # the client lost its scheduler, say
            logger.warning("rehearsal %s: watcher stopped: %s", self.id, exc)
            self._finish("failed", f"{type(exc).__name__}: {exc}")

    def _finish(self, state: str, error: str | None) -> None:
        with self._lock:
            if self._state in FINAL_STATES:
                return
            self._state, self._error = state, error
            self.finished_at_s = time.monotonic()
        self._release()
        self._finished.set()
        self._notify()

    def _release(self) -> None:
        """Drop the futures (the scheduler forgets their results and the inputs)."""
        with self._lock:
            self._inputs_future = None
            self._futures = []

    def _notify(self) -> None:
        with self._lock:
            progress = self._progress_locked()
            callbacks = list(self._callbacks)
        for callback in callbacks:
            try:
                callback(progress)
            except Exception:
                logger.exception("rehearsal %s: a progress callback failed", self.id)
