"""Rehearsal campaigns inside the server: one Dask cluster, a registry, limits, storage.

``RehearsalService`` owns the server's one cluster (``server.rehearsal.cluster``): an
embedded ``LocalCluster`` started on the first campaign, or a client of the scheduler
``roverops serve --dask-scheduler`` (``ROVEROPS_DASK_SCHEDULER``) names. ``submit`` stores
a campaign ``queued`` and answers at once; a thread of its own then gathers the inputs
(``server.rehearsal.gather``: what the ground knows), starts or joins the cluster, warms
its workers (the start and warm-up are timed apart: ``warmup_s``), runs the campaign
(``server.rehearsal.campaign.Campaign``), and stores its end: the risk table
(``server.rehearsal.risk.risk_table``) and the runs' outcomes
(``server.storage.rehearsals``). A user runs at most ``MAX_RUNNING_PER_USER`` campaigns at
once (queued or running): one more is refused (``CampaignLimitError``). ``cancel`` stops
one, keeping the runs finished. ``close`` (the server's shutdown) cancels every campaign
not over, stores it ``cancelled`` ("server stopped") and stops the cluster: no worker
process outlives the server. A campaign still ``queued`` or ``running`` in the database
when a service starts (its server was killed) is stored so too.
"""

from __future__ import annotations

import logging
import math
import threading
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from server.errors import ConflictError, DomainError, NotFoundError
from server.rehearsal.campaign import Campaign
from server.rehearsal.cluster import DEFAULT_RUN, RehearsalCluster, RunRef
from server.rehearsal.risk import risk_table, zones_in_mission
from server.storage import rehearsals as stored
from server.storage.store import Store
from sim.rehearsal.inputs import RehearsalInputs
from sim.rehearsal.outcome import RunOutcome

log = logging.getLogger(__name__)

MAX_RUNNING_PER_USER = 2  # campaigns one user may have queued or running at once
PROGRESS_STORE_S = 1.0  # the stored ``done`` is brought up to date at most this often
PARTIAL_RISK_S = 2.0  # a running campaign's partial risk table is recomputed at most so often
JOIN_S = 10.0  # how long ``close`` waits for a campaign's thread


def campaign_risk(inputs: RehearsalInputs, outcomes: Sequence[RunOutcome]) -> dict[str, Any]:
    """The risk table of a campaign's ``outcomes`` (``server.rehearsal.risk.risk_table``)
    with the keep-out zones and the tilt limit the rover reported."""
    limit_rad = inputs.start.params.get("mobility.tilt_limit_rad")
    kwargs: dict[str, Any] = {}
    if limit_rad is not None and math.isfinite(limit_rad) and limit_rad > 0.0:
        kwargs["tilt_limit_deg"] = math.degrees(limit_rad)
    return risk_table(inputs.sequence_text, outcomes,
                      keepout_zones_mission=zones_in_mission(inputs.start), **kwargs)  # fmt: skip


class CampaignLimitError(DomainError):
    """A user already runs ``MAX_RUNNING_PER_USER`` campaigns (HTTP 429)."""


@dataclass
class _Job:
    """A campaign this server runs: its stored summary, its ``Campaign`` once started."""

    summary: dict[str, Any]
    campaign: Campaign | None = None
    cancelled: str | None = None  # why, once cancel or close asked
    thread: threading.Thread | None = None
    stored_done_at: float = 0.0
    inputs: RehearsalInputs | None = None
    partial: tuple[int, float, dict[str, Any] | None] = (-1, 0.0, None)
    lock: threading.Lock = field(default_factory=threading.Lock)


class RehearsalService:
    """The server's campaigns (module docstring). ``scheduler``: a Dask scheduler's
    ``tcp://host:port`` (None: an embedded cluster of ``n_workers`` processes, default one
    per core); ``run`` the run function's reference (the engine's, by default)."""

    def __init__(
        self, store: Store, scheduler: str | None = None, n_workers: int | None = None,
        run: RunRef = DEFAULT_RUN,
    ) -> None:  # fmt: skip
        self.store = store
        self.scheduler = scheduler or None
        self.n_workers = n_workers
        self.run = run
        self._jobs: dict[int, _Job] = {}
        self._lock = threading.Lock()
        self._cluster: RehearsalCluster | None = None
        self._cluster_lock = threading.Lock()
        self._closed = False
        for found in stored.stop_unfinished(store):
            log.warning("rehearsal %d: left unfinished by a stopped server: cancelled", found)

    # ---- requests ------------------------------------------------------------------

    def submit(
        self, rover: str, user: str, runs: int, seed: int, sequence_id: int | None,
        sequence_text: str, gather: Callable[[], RehearsalInputs],
    ) -> dict[str, Any]:  # fmt: skip
        """Store a campaign ``queued`` and start it in a thread of its own (``gather``
        gives its inputs there); its summary. ``CampaignLimitError`` past the user's
        limit, ``ConflictError`` once the service is closed."""
        with self._lock:
            if self._closed:
                raise ConflictError("the server is stopping: no new rehearsal")
            running = [j for j in self._jobs.values() if j.summary["user"] == user
                       and j.summary["state"] in stored.UNFINISHED]  # fmt: skip
            if len(running) >= MAX_RUNNING_PER_USER:
                ids = ", ".join(f"#{j.summary['id']}" for j in running)
                raise CampaignLimitError(
                    f"{user} already runs {len(running)} rehearsal campaigns ({ids}); at most "
                    f"{MAX_RUNNING_PER_USER} at once per user (MAX_RUNNING_PER_USER): wait "
                    "for one to finish or cancel it"
                )
            summary = stored.add_rehearsal(self.store, rover, user, runs, seed, sequence_id,
                                           sequence_text)  # fmt: skip
            job = _Job(summary)
            self._jobs[summary["id"]] = job
            job.thread = threading.Thread(
                target=self._run_job, args=(job, gather), daemon=True,
                name=f"rehearsal-{summary['id']}",
            )  # fmt: skip
            job.thread.start()
        return self.summary(summary["id"])

    def cancel(self, rehearsal_id: int, why: str = "cancelled") -> dict[str, Any]:
        """Cancel a campaign not over (the runs finished are kept); its summary.
        ``NotFoundError`` / ``ConflictError`` for none or one already over."""
        job = self._jobs.get(rehearsal_id)
        if job is None or job.summary["state"] not in stored.UNFINISHED:
            found = stored.get_rehearsal(self.store, rehearsal_id)
            if found is None:
                raise NotFoundError(f"no rehearsal {rehearsal_id}")
            raise ConflictError(f"rehearsal {rehearsal_id} is {found['state']}, not running")
        self._cancel(job, why)
        return self.summary(rehearsal_id)

    def summary(self, rehearsal_id: int, with_risk: bool = False) -> dict[str, Any]:
        """A campaign's summary (its live progress while this server runs it), with its
        ``risk`` table when asked (a running campaign's: of its finished runs)."""
        job = self._jobs.get(rehearsal_id)
        found = stored.get_rehearsal(self.store, rehearsal_id)
        if found is None:
            raise NotFoundError(f"no rehearsal {rehearsal_id}")
        risk = found.pop("risk")
        out = {**found, "eta_s": None}
        if job is not None:
            with job.lock:
                out["state"] = job.summary["state"]
                campaign = job.campaign
            if campaign is not None and out["state"] == "running":
                progress = campaign.progress()
                out["done"], out["eta_s"] = progress.done, progress.eta_s
                if with_risk:
                    risk = self._partial_risk(job, campaign)
        if with_risk:
            out["risk"] = risk
        return out

    def campaigns(self, rover: str) -> list[dict[str, Any]]:
        """A rover's campaigns, newest first, with live progress."""
        return [self.summary(s["id"]) if s["id"] in self._jobs else {**s, "eta_s": None}
                for s in stored.list_rehearsals(self.store, rover)]  # fmt: skip

    def wait(self, rehearsal_id: int, timeout_s: float | None = None) -> bool:
        """Wait for this server's campaign to end (stored); True if it has."""
        job = self._jobs.get(rehearsal_id)
        if job is None or job.thread is None:
            return True
        job.thread.join(timeout_s)
        return not job.thread.is_alive()

    def running_pids(self) -> list[int]:
        """The embedded cluster's worker processes (none without one)."""
        cluster = self._cluster
        if cluster is None or not cluster.embedded:
            return []
        pids = cluster.client.run(lambda: __import__("os").getpid())
        return sorted(int(p) for p in pids.values())

    def close(self) -> None:
        """Cancel every campaign not over ("server stopped"), wait for their threads, stop
        the cluster (module docstring)."""
        with self._lock:
            self._closed = True
            jobs = list(self._jobs.values())
        for job in jobs:
            if job.summary["state"] in stored.UNFINISHED:
                self._cancel(job, stored.SERVER_STOPPED)
        for job in jobs:
            if job.thread is not None:
                job.thread.join(JOIN_S)
        with self._cluster_lock:
            cluster, self._cluster = self._cluster, None
        if cluster is not None:
            cluster.close()
        stored.stop_unfinished(self.store)  # a thread that did not end in time

    # ---- inside ----------------------------------------------------------------------

    def cluster(self) -> RehearsalCluster:
        """The server's cluster, started (or joined) on first use."""
        with self._cluster_lock:
            if self._closed:
                raise ConflictError("the server is stopping")
            if self._cluster is None:
                if self.scheduler:
                    self._cluster = RehearsalCluster.connect(self.scheduler)
                else:
                    self._cluster = RehearsalCluster.local(self.n_workers)
            return self._cluster

    def _cancel(self, job: _Job, why: str) -> None:
        with job.lock:
            if job.summary["state"] not in stored.UNFINISHED:
                return
            job.cancelled = why
            job.summary["state"] = "cancelled"
            campaign = job.campaign
        if campaign is not None:
            campaign.cancel()
        error = None if why == "cancelled" else why
        stored.update_rehearsal(self.store, job.summary["id"], state="cancelled", error=error,
                                done=campaign.progress().done if campaign else 0)  # fmt: skip

    def _set(self, job: _Job, **values: Any) -> bool:
        """Store ``values`` unless the campaign was cancelled meanwhile; whether stored."""
        with job.lock:
            if job.cancelled is not None:
                return False
            if "state" in values:
                job.summary["state"] = values["state"]
        stored.update_rehearsal(self.store, job.summary["id"], **values)
        return True

    def _run_job(self, job: _Job, gather: Callable[[], RehearsalInputs]) -> None:
        rid = job.summary["id"]
        try:
            inputs = job.inputs = gather()
            if job.cancelled is not None:
                return
            cluster = self.cluster()
            warmup_s = cluster.warm_up(self.run)
            campaign = Campaign(cluster, inputs, job.summary["runs"], job.summary["seed"],
                                self.run, campaign_id=f"{rid}-{uuid.uuid4().hex[:8]}",
                                start=False)  # fmt: skip
            campaign.on_progress(lambda progress: self._progressed(job, progress.done))
            with job.lock:
                if job.cancelled is not None:
                    return
                job.campaign = campaign
                job.summary["state"] = "running"
            stored.update_rehearsal(self.store, rid, state="running", warmup_s=warmup_s)
            campaign.start()
            campaign.wait()
            progress = campaign.progress()
            outcomes = campaign.outcomes()
            dicts = [o.as_dict() for o in outcomes]
            if progress.state == "done":
                self._set(job, state="done", done=len(outcomes), outcomes=dicts,
                          risk=campaign_risk(inputs, outcomes))  # fmt: skip
            elif progress.state == "cancelled":  # the runs finished are kept
                risk = campaign_risk(inputs, outcomes) if outcomes else None
                stored.update_rehearsal(self.store, rid, done=len(outcomes), outcomes=dicts,
                                        risk=risk)  # fmt: skip
            else:
                self._set(job, state="failed", done=len(outcomes), error=progress.error)
        except Exception as error:  # the cluster, the inputs, the storage: said, not raised
            log.warning("rehearsal %d failed: %s", rid, error, exc_info=True)
            self._set(job, state="failed", error=f"{type(error).__name__}: {error}")

    def _progressed(self, job: _Job, done: int) -> None:
        now = time.monotonic()
        if now - job.stored_done_at >= PROGRESS_STORE_S:
            job.stored_done_at = now
            self._set(job, done=done)

    def _partial_risk(self, job: _Job, campaign: Campaign) -> dict[str, Any] | None:
        """The risk table of the runs finished so far (recomputed at most every
        ``PARTIAL_RISK_S``, and only when more have finished)."""
        done, at, risk = job.partial
        now = time.monotonic()
        if now - at < PARTIAL_RISK_S:
            return risk
        outcomes = campaign.outcomes()
        if len(outcomes) != done and job.inputs is not None:
            risk = campaign_risk(job.inputs, outcomes) if outcomes else None
        job.partial = (len(outcomes), now, risk)
        return risk
