"""``roverops bench rehearsal``: issue 25's acceptance (``bench.rehearsal.suite`` puts the
parts together: ``pairs`` the calibration against executions, ``speed`` the campaigns on
Dask, ``live`` the live rovers beside a campaign inside the server)."""

from bench.rehearsal.suite import bench_rehearsal

__all__ = ["bench_rehearsal"]
