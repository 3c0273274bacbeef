"""Uploads validated in a separate process, so the event loop never waits for them.

Issue 13 (defect 4) asks that a 1 MB upload validating against a rover leave the other
requests answered within 100 ms (``event_loop_stall_ms_during_upload``, p99). Validating
in the threadpool keeps the work off the event loop but not off the interpreter lock: the
validating thread, the rovers' clock threads and the event loop take turns holding it, and
every request waited for it (92-287 ms p99 against ~3 ms idle). A process has its own lock.

- ``ValidationPool(processes)`` owns a ``ProcessPoolExecutor`` of ``processes`` workers
  started with "spawn": the server has many threads (uvicorn, rover clocks, viser, the
  storage writer) and a forked child would inherit the locks they hold. ``start`` creates
  it and warms the worker (imports, the ephemeris, one validation) in the background, so
  the first upload does not pay for it; ``stop`` ends the workers (a validation has
  nothing to save).
- ``check`` sends the worker plain values only: the body's bytes, its content type, the
  rover's ``RoverSite`` (from which the worker builds its ``ValidationContext``) and
  whether to find a name. The worker answers a ``Checked``, or the ``HTTPException`` of a
  bad body (``server.validation.uploads.read_source``) as a ``Refused`` of plain values,
  raised again here: exceptions do not always survive pickling.
- A worker that dies (killed, out of memory) breaks the pool: the request is retried once
  in a new pool; if that worker dies too, the request is validated in the threadpool
  (the old path, slower for the others but an answer, not a 5xx), and the next upload
  gets a new pool again.
- ``processes=0``: no pool, every validation in the threadpool (tests that hold a
  validation on a ``threading.Event`` use it: an event cannot cross processes).
- Each worker ends itself when the server process dies (SIGKILL included): a worker waits
  on its queue, which it holds both ends of, and would otherwise outlive the server. It
  ignores SIGINT: Ctrl-C stops the server, which then ends its workers.

Used from the event loop only (no lock needed); the immediate-command route validates one
step and stays in-process.
"""

from __future__ import annotations

import asyncio
import json
import logging
import multiprocessing
import os
import signal
import threading
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from multiprocessing.connection import wait
from typing import Any

from fastapi import HTTPException
from starlette.concurrency import run_in_threadpool

from sequences.language import declared_name
from sequences.validate import ValidationContext, ValidationResult, validate
from server.validation.context import RoverSite
from server.validation.uploads import read_source

logger = logging.getLogger(__name__)

WARM_SEQUENCE = "SEQUENCE warm\nNADIR_UPDATE\nHGA_PASS\n"  # the ephemeris, the predicting walk
STOP_JOIN_S = 5.0  # how long ``stop`` waits for a terminated worker


@dataclass
class Checked:
    """An upload read and validated: its source as stored, format, name and result."""

    text: str
    fmt: str
    name: str
    result: ValidationResult


@dataclass
class Refused:
    """An ``HTTPException`` as plain values, to cross the process boundary."""

    status_code: int
    detail: Any
    headers: dict[str, str] | None


def check_upload(
    body: bytes, content_type: str, context: ValidationContext | None, named: bool
) -> Checked:
    """Everything that grows with an upload, in one call (never on the event loop):
    decoding, JSON parsing, validation and the name (the declared one when ``named``)."""
    source, fmt = read_source(body, content_type)
    result = validate(source, context)
    name = (result.sequence.name if result.sequence else None) or (
        (declared_name(source) or "unnamed") if named else "unnamed"
    )
    text = source if isinstance(source, str) else json.dumps(source)
    return Checked(text, fmt, name, result)


def _check_in_worker(
    body: bytes, content_type: str, site: RoverSite | None, named: bool
) -> Checked | Refused:
    """``check_upload`` in a worker, the rover's context built here from ``site``."""
    try:
        return check_upload(body, content_type, site.context() if site else None, named)
    except HTTPException as refused:
        headers = dict(refused.headers) if refused.headers else None
        return Refused(refused.status_code, refused.detail, headers)


def _warm(site: RoverSite | None) -> None:
    """What the first upload would otherwise wait for: one small validation."""
    check_upload(WARM_SEQUENCE.encode(), "text/plain", site.context() if site else None, True)


def _init_worker() -> None:
    """A worker's initializer: a thread that ends the worker when the server is gone. An
    operator's Ctrl-C (SIGINT to the whole process group) is left to the server, which
    ends its workers as it stops."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    parent = multiprocessing.parent_process()
    if parent is None or parent.sentinel is None:
        return

    def watch(sentinel: int) -> None:
        wait([sentinel])
        os._exit(0)

    threading.Thread(target=watch, args=(parent.sentinel,), daemon=True).start()


class ValidationPool:
    """Upload validation in ``processes`` worker processes (0: in the threadpool)."""

    def __init__(self, processes: int) -> None:
        if processes < 0:
            raise ValueError(f"processes: must be 0 or more, got {processes}")
        self.processes = processes
        self._pool: ProcessPoolExecutor | None = None

    def start(self, warm_site: RoverSite | None = None) -> None:
        """The workers started and warmed (in the background) with ``warm_site``'s context."""
        if self.processes:
            self._pool = self._new_pool()
            self._pool.submit(_warm, warm_site)  # its answer is not needed

    def stop(self) -> None:
        """The workers ended, whatever they are doing (a warm-up, at most: the server
        answers its requests before it stops)."""
        pool, self._pool = self._pool, None
        if pool is None:
            return
        workers = list(pool._processes.values())  # no public way to end a busy worker
        pool.shutdown(wait=False, cancel_futures=True)
        for worker in workers:
            worker.terminate()
        for worker in workers:
            worker.join(STOP_JOIN_S)

    def worker_pids(self) -> list[int]:
        """The pool's worker process ids (none before the first task has started one)."""
        return list(self._pool._processes) if self._pool is not None else []

    async def check(
        self, body: bytes, content_type: str, site: RoverSite | None, named: bool
    ) -> Checked:
        """``check_upload`` of an upload in a worker (module docstring); a bad body's
        ``HTTPException`` raised here."""
        for _ in range(2):  # a broken pool: once more in a new one
            pool = self._pool
            if pool is None:
                break
            try:
                answer = await asyncio.wrap_future(
                    pool.submit(_check_in_worker, body, content_type, site, named)
                )
            except BrokenProcessPool:
                self._replace(pool)
                continue
            if isinstance(answer, Refused):
                raise HTTPException(answer.status_code, answer.detail, answer.headers)
            return answer
        if self._pool is not None:
            logger.warning("validation workers died twice in a row; validating in a thread")
        context = site.context() if site else None
        return await run_in_threadpool(check_upload, body, content_type, context, named)

    def _replace(self, broken: ProcessPoolExecutor) -> None:
        """A new pool for a broken one (once, however many requests found it broken)."""
        if self._pool is not broken:
            return
        logger.warning("a validation worker died; starting a new one")
        broken.shutdown(wait=False, cancel_futures=True)
        self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            self.processes,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_worker,
        )
