"""When a sequence step starts: its time tag read against the rover's clock.

The pure arithmetic the server's queue (``server.queue``) and a rehearsal
(``sim.rehearsal.run``) share, so that a rehearsed sequence starts its steps exactly when the
rover would. The Mars clock (sol numbers and LMST, Allison and McEwen 2000) is given as two
functions of the mission, so this module stays free of the simulator.
"""

from __future__ import annotations

from collections.abc import Callable

from sequences.model import TimeTag

SolOf = Callable[[float], int]
"""The mission's sol number at a time (TT s since J2000)."""
TimeAt = Callable[[int, float], float]
"""The time (TT s) when the mission's LMST reads ``lmst_h`` on sol ``sol``."""


def start_time(
    tag: TimeTag, now_t_s: float, last_done_t_s: float, sol_of: SolOf, time_at: TimeAt
) -> float:
    """When a step with time tag ``tag`` starts (TT s), the rover at ``now_t_s``, its
    previous command done at ``last_done_t_s``: a relative tag that long after it, a
    sol-and-LMST tag at that moment, an LMST tag the next time the rover's LMST reads it
    (now included), no tag now."""
    if tag.kind == "relative":
        return last_done_t_s + float(tag.after_s or 0.0)
    lmst_h = float(tag.lmst_h or 0.0)
    if tag.kind == "sol_lmst":
        return time_at(int(tag.sol or 0), lmst_h)
    if tag.kind == "lmst":
        sol = int(sol_of(now_t_s))
        t = time_at(sol, lmst_h)
        return t if t >= now_t_s - 1e-6 else time_at(sol + 1, lmst_h)
    return now_t_s
