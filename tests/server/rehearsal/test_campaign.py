"""Campaigns on a real embedded Dask cluster (two worker processes, shared by this module):
the workers' settings, progress to the end, a failing run, cancel, and results that do not
depend on the number of workers."""

from __future__ import annotations

import math
import socket
import threading
from collections.abc import Iterator

import pytest
from distributed import Event

from server.rehearsal.campaign import Campaign, Progress
from server.rehearsal.cluster import RehearsalCluster, _warm_up, validate_address
from sim.rehearsal.inputs import GroundMapData, RehearsalInputs, ReportedStart
from sim.rehearsal.outcome import RunOutcome
from tests.server.rehearsal import rehearsal_tasks as tasks

TASKS = "tests.server.rehearsal.rehearsal_tasks"
SEQUENCE = (
    "SEQUENCE t\nDRIVE_STRAIGHT distance_m=2.0\nWAIT duration_s=30\nDRIVE_STRAIGHT distance_m=1.5\n"
)
WAIT_S = 60.0  # an upper bound on a campaign of a few cheap runs, never reached when right


def _inputs(sequence: str = SEQUENCE) -> RehearsalInputs:
    import numpy as np

    start = ReportedStart(
        site="gusev",
        mission="spirit",
        t_s=1.0e8,
        q_b_ll_est=(0.0, 0.0, math.sin(0.3), math.cos(0.3)),
        p_s_est=(1.0, 2.0, 0.0),
        p_mission_est=(11.0, 22.0, 0.0),
        aqf="Coarse",
        position_sigma_m=0.2,
    )
    grid = np.zeros((3, 3))
    ground = GroundMapData(0.0, 0.0, 1.0, grid, grid + 0.1, grid + 0.2, grid > 0)
    return RehearsalInputs(start=start, ground_map=ground, sequence_text=sequence)


@pytest.fixture(scope="module")
def cluster() -> Iterator[RehearsalCluster]:
    with RehearsalCluster.local(n_workers=2) as c:
        yield c


def test_workers_run_numba_on_one_thread_niced_and_warmed(cluster: RehearsalCluster) -> None:
    assert len(cluster.workers()) == 2 and cluster.slots() == 2
    warmup_s = cluster.warm_up(f"{TASKS}:kinematic_run")
    assert warmup_s >= cluster.start_s > 0.0
    assert sorted(cluster.warmup_task_s) == cluster.workers()
    assert set(cluster.client.run(tasks.warmed).values()) == {1}  # once on each worker
    assert cluster.warm_up(f"{TASKS}:kinematic_run") == warmup_s  # not again
    assert set(cluster.client.run(tasks.warmed).values()) == {1}
    # in the worker's event loop thread, and in the thread that runs the tasks
    for env, numba_threads, nice, thread_nice in cluster.client.run(tasks.worker_settings).values():
        assert (env, numba_threads) == ("1", 1)
        assert nice >= 10 and thread_nice >= 10
    futures = [cluster.client.submit(tasks.worker_settings, pure=False) for _ in range(4)]
    for env, numba_threads, nice, thread_nice in cluster.client.gather(futures):
        assert (env, numba_threads, nice >= 10, thread_nice >= 10) == ("1", 1, True, True)


def test_a_campaign_runs_to_the_end_with_progress(cluster: RehearsalCluster) -> None:
    seen: list[Progress] = []
    campaign = Campaign(
        cluster, _inputs(), runs=9, seed=7, run=f"{TASKS}:kinematic_run", start=False
    )
    campaign.on_progress(seen.append)
    assert campaign.progress() == Progress(0, 9, None, "queued")
    campaign.start()
    assert campaign.wait(WAIT_S)
    final = campaign.progress()
    assert (final.done, final.total, final.state, final.eta_s, final.error) == (
        9,
        9,
        "done",
        0.0,
        None,
    )
    outcomes = campaign.outcomes()
    assert [o.run_index for o in outcomes] == list(range(9))
    assert all(o.wall_s > 0.0 and o.worker in cluster.workers() for o in outcomes)
    assert [len(o.steps) for o in outcomes] == [3] * 9
    assert [o.steps[1].line for o in outcomes] == [3] * 9
    # a notice as the runs go, one per run and one at the end; done counts up to the total
    assert seen[0] == Progress(0, 9, None, "running")
    assert len(seen) == 11 and [p.done for p in seen[1:10]] == list(range(1, 10))
    assert seen[-1].state == "done"
    running = [p for p in seen[1:9] if p.state == "running"]
    assert running and all(p.eta_s is not None and p.eta_s > 0.0 for p in running)
    assert campaign.cancel().state == "done"  # over: cancel changes nothing


def test_results_do_not_depend_on_the_workers(cluster: RehearsalCluster) -> None:
    two = Campaign(cluster, _inputs(), runs=6, seed=11, run=tasks.kinematic_run)
    with RehearsalCluster.local(n_workers=1) as single:
        one = Campaign(single, _inputs(), runs=6, seed=11, run=f"{TASKS}:kinematic_run")
        assert one.wait(WAIT_S) and two.wait(WAIT_S)
    # repr: the same bits, NaN included (NaN != NaN)
    assert [repr(o.steps) for o in one.outcomes()] == [repr(o.steps) for o in two.outcomes()]
    assert {o.worker for o in two.outcomes()} <= set(cluster.workers())
    other_seed = Campaign(cluster, _inputs(), runs=6, seed=12, run=tasks.kinematic_run)
    assert other_seed.wait(WAIT_S)
    assert [repr(o.steps) for o in other_seed.outcomes()] != [repr(o.steps) for o in two.outcomes()]


def test_a_failing_run_fails_the_campaign_with_its_error(cluster: RehearsalCluster) -> None:
    campaign = Campaign(cluster, _inputs(), runs=8, seed=0, run=f"{TASKS}:failing_run")
    assert campaign.wait(WAIT_S)
    progress = campaign.progress()
    assert progress.state == "failed"
    assert progress.error == f"run {tasks.FAIL_AT}: RuntimeError: the world of run 3 has no ground"
    assert tasks.FAIL_AT not in [o.run_index for o in campaign.outcomes()]


def test_cancel_stops_the_runs_and_keeps_those_done(cluster: RehearsalCluster) -> None:
    gate = Event(tasks.GATE_EVENT, client=cluster.client)
    gate.clear()
    two_done = threading.Event()
    campaign = Campaign(cluster, _inputs(), runs=20, seed=3, run=f"{TASKS}:gated_run", start=False)
    campaign.on_progress(lambda p: two_done.set() if p.done >= tasks.GATE_FROM else None)
    campaign.start()
    try:
        assert two_done.wait(WAIT_S)
        assert campaign.state == "running"
        progress = campaign.cancel()
        assert (progress.state, progress.done, progress.total) == ("cancelled", 2, 20)
        assert campaign.wait(0.0)
        assert [o.run_index for o in campaign.outcomes()] == [0, 1]
    finally:
        gate.set()  # frees the two runs the workers hold
    assert campaign.progress().done == 2  # runs finishing after the cancel are not taken


def test_connect_validates_the_address_and_reaches_a_scheduler(cluster: RehearsalCluster) -> None:
    for bad in (
        "http://localhost:8786",
        "tcp://localhost",
        "tcp://local host:1",
        "tcp://h:99999",
        8786,
    ):
        with pytest.raises(ValueError, match="dask scheduler"):
            validate_address(bad)
    address = cluster.client.scheduler.address
    with RehearsalCluster.connect(address) as remote:
        assert not remote.embedded and remote.workers() == cluster.workers()
        campaign = Campaign(remote, _inputs(), runs=3, seed=1, run=f"{TASKS}:kinematic_run")
        assert campaign.wait(WAIT_S) and campaign.state == "done"
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ConnectionError, match=f"tcp://127.0.0.1:{port}"):
        RehearsalCluster.connect(f"tcp://127.0.0.1:{port}", timeout_s=1.0)


def test_bad_campaign_arguments_are_refused(cluster: RehearsalCluster) -> None:
    for runs in (0, 1001, 2.0, True):
        with pytest.raises(ValueError, match="runs"):
            Campaign(cluster, _inputs(), runs=runs, start=False)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="seed"):
        Campaign(cluster, _inputs(), runs=1, seed=-1, start=False)
    with pytest.raises(ValueError, match="run"):
        Campaign(cluster, _inputs(), runs=1, run="not a reference", start=False)
    with pytest.raises(ValueError, match="inputs"):
        Campaign(cluster, "inputs", runs=1, start=False)  # type: ignore[arg-type]


def test_warm_up_without_a_warm_up_function_makes_one_throwaway_run() -> None:
    calls: list[tuple[int, int]] = []

    def counting_run(inputs: RehearsalInputs, run_index: int, seed: int) -> RunOutcome:
        calls.append((run_index, seed))
        return tasks.kinematic_run(inputs, run_index, seed)

    assert _warm_up(counting_run) >= 0.0 and calls == []  # no inputs: an import only
    assert _warm_up(counting_run, _inputs()) >= 0.0 and calls == [(0, 0)]
    before = tasks.warmed()
    _warm_up(f"{TASKS}:kinematic_run", _inputs())  # the module's own warm_up(), no run
    assert tasks.warmed() == before + 1
