"""The ground's view of a rover's link (``GET /api/rovers/{rover}/comm``): its mode and plan,
the light time now (DE421), the windows past and predicted (``sim.comm.windows``, from the
published ephemerides), what each past pass brought down, what waits to go up, the onboard
store as the rover last reported it, and how old the newest data on the ground is.

Only ground knowledge: the link's ``ground_view`` (``server.comm.mission``), the ephemerides,
the rover's last downlink record (``RoverRuntime.last_frame``)."""

from __future__ import annotations

from typing import Any

from server.runtime import RoverRuntime
from sim.comm.windows import Window, comm_windows
from sim.world.light_time import one_way_light_time_s
from sim.world.marsclock import SOL_S, get_mission, t_s_to_utc

MAX_SPAN_S = 10.0 * SOL_S  # the longest span of windows one request may ask for


def when(runtime: RoverRuntime, t_s: float | None) -> dict[str, Any] | None:
    """A moment as the console shows it: TT seconds, UTC, sol and LMST."""
    if t_s is None:
        return None
    return {"t_s": t_s, "utc": t_s_to_utc(t_s).isoformat(), "sol": runtime.sol(t_s),
            "lmst_h": runtime.lmst_h(t_s)}  # fmt: skip


def _window(
    runtime: RoverRuntime, w: Window, passes: dict[tuple[str, float], dict[str, Any]]
) -> dict[str, Any]:
    out = {**w.as_json(), "start": when(runtime, w.start_t_s), "end": when(runtime, w.end_t_s)}
    got = passes.get((w.kind, round(w.start_t_s, 3)))  # an uplink window brings nothing down
    out["received_mbit"] = None if got is None else got["bits"] / 1e6
    out["received_products"] = None if got is None else got["products"]
    return out


def comm_json(runtime: RoverRuntime, t_from_s: float | None = None,
              t_to_s: float | None = None) -> dict[str, Any]:  # fmt: skip
    """The answer of ``GET /api/rovers/{rover}/comm`` (module docstring); windows over
    [t_from_s, t_to_s], by default a sol back and two ahead."""
    now = runtime.t_s
    t_from_s = now - SOL_S if t_from_s is None else t_from_s
    t_to_s = now + 2.0 * SOL_S if t_to_s is None else t_to_s
    comm = runtime.comm
    site = get_mission(runtime.spec.mission)
    found = comm_windows(site.lat_deg, site.lon_east_deg, comm.plan, t_from_s, t_to_s)
    ground = comm.mission.ground_view() if comm.mission is not None else None
    passes = {(p["via"], round(p["start_t_s"], 3)): p for p in (ground or {}).get("passes", [])}
    ahead = [w for w in comm_windows(site.lat_deg, site.lon_east_deg, comm.plan, now,
                                     now + 3.0 * SOL_S) if w.end_t_s > now]  # fmt: skip
    next_uplink = next((w for w in ahead if w.kind == "uplink"), None)
    next_pass = next((w for w in ahead if w.kind != "uplink"), None)
    last = runtime.last_frame
    received = comm.last_received_t_s
    store = None if ground is None else ground["store"]
    return {
        "rover": runtime.spec.name,
        "mode": comm.mode,
        "plan": comm.plan.as_json(),
        "now": when(runtime, now),
        "one_way_light_time_s": float(one_way_light_time_s(now)),
        "next_uplink": None if next_uplink is None else _window(runtime, next_uplink, passes),
        "next_pass": None if next_pass is None else _window(runtime, next_pass, passes),
        "windows": [_window(runtime, w, passes) for w in found],
        "store": None if store is None else {
            **store, "fill_pct": 100.0 * store["used_bits"] / store["capacity_bits"],
            "reported": when(runtime, store["t_s"]),
            "received": when(runtime, store["received_t_s"])},
        "uplinks": [] if ground is None else [*ground["waiting"], *ground["rising"]],
        "gaps": [] if ground is None else ground["gaps"],
        "newest_data": None if last is None else {
            "data": when(runtime, float(last["t_s"])),
            "received": when(runtime, received),
            "age_s": now - float(last["t_s"]),
            "received_ago_s": None if received is None else now - received},
    }  # fmt: skip
