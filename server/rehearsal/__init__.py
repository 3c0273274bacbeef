"""Rehearsal campaigns on the server (issue 25): a sequence rehearsed many times on sampled
worlds, from what the ground knows, on Dask."""
