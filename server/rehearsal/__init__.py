"""Rehearsal campaigns: a sequence run hundreds of times on Dask over worlds sampled from
what the ground knows (``sim.rehearsal.inputs``), and what comes back: the risk table and
the report of predicted against executed."""
