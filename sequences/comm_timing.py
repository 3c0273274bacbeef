"""Planning across the light time (issue 23): when a sequence can be onboard, and when a
drive's results can be on the ground for the next sol's plan.

MER was operated across 3 to 22 minutes of light time on a daily cycle: the sol's sequences
went up in the morning uplink window, and a sol's plan could build on a drive only if the
drive's results had reached the ground by the time planning started; otherwise the next sol
was a *restricted sol* (Mishkin, Limonadi, Laubach and Bass 2006). With a rover whose link
crosses the light time (``roverops serve --comm mission``) the ground's validation context
carries its link as plain numbers (``CommTiming``, made by ``server.validation.comm_context``
from ``sim.comm``'s windows and ``sim.world.light_time``); this module predicts from them
without importing the simulator:

- **Onboard.** The ground radiates the sequence, ``UPLINK_HEADER_BITS`` plus 8 bits per byte
  of its text form (``sequences.language.to_text``, UTF-8: what the link sends), over the
  uplink window's rate, from ``uplink_from_t_s`` (the validation moment, or later when
  uplinks already wait on the ground), in the first uplink window that holds it whole and
  opens before ``uplink_until_t_s`` (10 sols on: the link's search). It is onboard a light
  time after its radiation ends. The walk starts there (``sequences.validate``): untagged
  steps start once onboard, and a time-tagged step whose time comes before it is warned
  (``before-onboard``). No window: ``no-uplink``, and the walk starts at the validation
  moment.
- **Results on the ground.** A drive's results go down in the first downlink window (relay
  or direct-to-Earth) open at the drive's predicted end or opening after it (where two are
  open, the faster, as the link chooses), assumed to have room for them: sent at the later
  of the drive's end and the window's opening, they reach the ground after the relay's
  store-and-forward latency (relay only) and the light time. If that is after
  ``planning_lmst_h`` LMST of the sol the drive ends, that sol's plan cannot build on the
  drive (``restricted-sol``); a drive ending after that LMST is always too late. Drives
  ending past ``horizon_t_s`` (the end of the windows the context holds: at least 3 sols
  past the latest onboard time it can give) are not checked.

The light time changes by less than 0.1 s a minute (about 5 s a sol at most): the context
samples it (a quarter sol apart from the server) and it is interpolated linearly, well
within a second; a single sample stands for the whole span, which within a sol is good to
a few seconds. The uplink's light time is the one that reaches Mars at ``t`` (``t_a = t_r +
τ_up(t_a)``), the downlink's the one that leaves Mars at ``t``; they differ by up to a
quarter of a second.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal, Protocol

from sequences import commands as cmd
from sequences.language import to_text
from sequences.model import Sequence as Steps
from sequences.model import SequenceStep

__all__ = [
    "UPLINK_HEADER_BITS",
    "CommTiming",
    "CommWalk",
    "LinkWindow",
    "radiation",
    "uplink_bits",
]

UPLINK_HEADER_BITS = 48  # a CCSDS space packet's primary header (sim.comm.store.HEADER_BITS)
DRIVES = (cmd.DriveStraight, cmd.DriveArc, cmd.TurnInPlace, cmd.DriveTo)
WindowKind = Literal["uplink", "relay", "dte"]
Warn = Callable[[SequenceStep, str, str], None]
_EPS_S = 1e-6


@dataclass(frozen=True)
class LinkWindow:
    """One window of the link (``sim.comm.windows.Window`` as plain numbers): TT seconds
    since J2000 and the rate, bit/s."""

    kind: WindowKind
    start_t_s: float
    end_t_s: float
    rate_bps: float


def radiation(
    windows: Sequence[LinkWindow], bits: int, after_t_s: float, until_t_s: float
) -> tuple[float, float] | None:
    """When ``bits`` go up, from ``after_t_s`` on: (first bit, last bit) inside the first
    uplink window of ``windows`` (sorted by start) that holds them whole and opens before
    ``until_t_s``; ``None`` if none does (``sim.comm.link.CommLink.radiation``'s rule).

    >>> w = [LinkWindow("uplink", 100.0, 200.0, 2.0)]
    >>> radiation(w, 40, 0.0, 1e9), radiation(w, 40, 150.0, 1e9), radiation(w, 400, 0.0, 1e9)
    ((100.0, 120.0), (150.0, 170.0), None)
    """
    for w in windows:
        if w.kind != "uplink" or w.end_t_s <= after_t_s:
            continue
        if w.start_t_s > until_t_s:
            break
        begin = max(after_t_s, w.start_t_s)
        end = begin + bits / w.rate_bps
        if end <= w.end_t_s:
            return begin, end
    return None


def uplink_bits(sequence: Steps) -> int:
    """The bits the link radiates for ``sequence``: its text form and a packet header."""
    return UPLINK_HEADER_BITS + 8 * len(to_text(sequence).encode("utf-8"))


@dataclass(frozen=True)
class CommTiming:
    """A rover's link across the light time, for validation (module docstring).

    ``uplink_from_t_s``: the ground may radiate this sequence from then on (the validation
    moment, or when the uplinks waiting before it are out; ``inf`` if they never are);
    ``uplink_until_t_s``: uplink windows opening after it are not searched. ``windows``:
    uplink, relay and direct-to-Earth windows sorted by start, known up to ``horizon_t_s``.
    ``relay_latency_s``: the orbiter's store-and-forward delay; ``planning_lmst_h``: a
    drive's results are due on the ground by this LMST of its sol. ``light_t_s`` (ascending,
    at least one) samples the one-way light time: ``uplink_light_s`` of the light that
    reaches Mars at each, ``downlink_light_s`` of the light that leaves Mars at each.
    """

    uplink_from_t_s: float
    uplink_until_t_s: float
    windows: tuple[LinkWindow, ...]
    horizon_t_s: float
    relay_latency_s: float
    planning_lmst_h: float
    light_t_s: tuple[float, ...]
    uplink_light_s: tuple[float, ...]
    downlink_light_s: tuple[float, ...]

    def __post_init__(self) -> None:
        n = len(self.light_t_s)
        if n == 0 or len(self.uplink_light_s) != n or len(self.downlink_light_s) != n:
            raise ValueError("light_t_s, uplink_light_s, downlink_light_s: one value each")
        if any(b <= a for a, b in zip(self.light_t_s, self.light_t_s[1:], strict=False)):
            raise ValueError("light_t_s: must be ascending")
        if list(self.windows) != sorted(self.windows, key=lambda w: w.start_t_s):
            raise ValueError("windows: must be sorted by start_t_s")

    def onboard(self, bits: int) -> tuple[float, float] | None:
        """(radiation's end, onboard) for ``bits``; ``None`` if no window can radiate them."""
        if not math.isfinite(self.uplink_from_t_s):
            return None
        when = radiation(self.windows, bits, self.uplink_from_t_s, self.uplink_until_t_s)
        return None if when is None else (when[1], self.uplink_arrival_t_s(when[1]))

    def uplink_arrival_t_s(self, t_radiated_s: float) -> float:
        """When the light radiated from Earth at ``t_radiated_s`` reaches Mars."""
        arrival = t_radiated_s
        for _ in range(4):  # the light time changes by ~1e-4 s/s: converged in two
            arrival = t_radiated_s + _at(self.light_t_s, self.uplink_light_s, arrival)
        return arrival

    def downlink_arrival_t_s(self, t_sent_s: float) -> float:
        """When the light that leaves Mars at ``t_sent_s`` reaches Earth."""
        return t_sent_s + _at(self.light_t_s, self.downlink_light_s, t_sent_s)

    def results_on_ground(self, t_s: float) -> tuple[float, float, LinkWindow] | None:
        """What is made at ``t_s``: (sent, on the ground, the window that sends it), or
        ``None`` if no downlink window is open at ``t_s`` or opens after it."""
        best: tuple[float, LinkWindow] | None = None
        for w in self.windows:
            if w.kind == "uplink" or w.end_t_s <= t_s:
                continue
            sent = max(t_s, w.start_t_s)
            if best is None or sent < best[0]:
                best = (sent, w)
            elif sent > best[0]:
                break  # sorted by start: nothing later opens earlier
            elif (w.rate_bps, w.kind == "relay") > (best[1].rate_bps, best[1].kind == "relay"):
                best = (sent, w)  # open together: the faster carries it
        if best is None:
            return None
        sent, window = best
        latency = self.relay_latency_s if window.kind == "relay" else 0.0
        return sent, self.downlink_arrival_t_s(sent + latency), window


def _at(times: tuple[float, ...], values: tuple[float, ...], t_s: float) -> float:
    """``values`` at ``t_s``, linear between samples, the end values beyond them."""
    i = bisect.bisect_right(times, t_s)
    if i == 0:
        return values[0]
    if i == len(times):
        return values[-1]
    t0, t1 = times[i - 1], times[i]
    return values[i - 1] + (values[i] - values[i - 1]) * (t_s - t0) / (t1 - t0)


class _Context(Protocol):
    """What of ``sequences.validate.ValidationContext`` the walk reads."""

    @property
    def start_t_s(self) -> float: ...

    @property
    def sol(self) -> Callable[[float], int]: ...

    @property
    def t_s_for(self) -> Callable[[int, float], float]: ...

    def clock(self, t_s: float) -> str: ...


@dataclass
class CommWalk:
    """The walk's side of the link (module docstring): where it starts, the time tags that
    come before the sequence is onboard, and the drives whose results come too late."""

    warn: Warn
    ctx: _Context
    timing: CommTiming
    onboard_t_s: float | None  # None: no uplink window radiates it
    radiated_t_s: float | None

    @classmethod
    def start(cls, warn: Warn, ctx: _Context, timing: CommTiming, sequence: Steps) -> CommWalk:
        """The walk of ``sequence`` (which has steps); ``no-uplink`` at its first step if no
        window can radiate it."""
        bits = uplink_bits(sequence)
        when = timing.onboard(bits)
        if when is None:
            first = sequence.steps[0]
            if math.isfinite(timing.uplink_from_t_s):
                since = f"from {ctx.clock(timing.uplink_from_t_s)}"
            else:
                since = "after the uplinks already waiting on the ground"
            text = (
                f"no uplink window before {ctx.clock(timing.uplink_until_t_s)} can radiate "
                f"this sequence ({bits} bits) {since}: it waits on the ground; the other "
                "warnings are predicted as if it were onboard now"
            )
            warn(first, "no-uplink", text)
            return cls(warn, ctx, timing, None, None)
        return cls(warn, ctx, timing, when[1], when[0])

    @property
    def start_t_s(self) -> float:
        """Where the walk starts: onboard, or the validation moment without an uplink."""
        return self.ctx.start_t_s if self.onboard_t_s is None else self.onboard_t_s

    def before_onboard(
        self, step: SequenceStep, tag_t_s: float, start_t_s: float, since_t_s: float = -math.inf
    ) -> bool:
        """Warn (``before-onboard``) if ``step``'s tag time ``tag_t_s`` (in
        ``[since_t_s, onboard)``) comes before the sequence is onboard; it starts at
        ``start_t_s`` instead. True when it warned."""
        onboard = self.onboard_t_s
        if onboard is None or not since_t_s <= tag_t_s < onboard - _EPS_S:
            return False
        tag = step.time_tag
        if tag.kind == "sol_lmst":
            words = f"sol {tag.sol} {tag.clock()} LMST"
        else:
            words = f"{tag.clock()} LMST of sol {self.ctx.sol(tag_t_s)}"
        assert self.radiated_t_s is not None
        light_min = (onboard - self.radiated_t_s) / 60.0
        then = (
            f"it starts late, at {self.ctx.clock(start_t_s)}"
            if tag.kind == "sol_lmst"
            else f"it waits until {self.ctx.clock(start_t_s)}"
        )
        text = (
            f"{words} comes before the sequence can be onboard ({self.ctx.clock(onboard)}: "
            f"radiated by {self.ctx.clock(self.radiated_t_s)}, then {light_min:.1f} min of "
            f"light time): {then}"
        )
        self.warn(step, "before-onboard", text)
        return True

    def step(self, step: SequenceStep, start_t_s: float, duration_s: float) -> None:
        """A drive's results against the planning deadline of the sol it ends."""
        if not isinstance(step.command, DRIVES):
            return
        ctx, timing = self.ctx, self.timing
        end = start_t_s + duration_s
        sol = ctx.sol(end)
        deadline = ctx.t_s_for(sol, timing.planning_lmst_h)
        due = f"{_hm(timing.planning_lmst_h)} LMST planning time (restricted sol)"
        if end > timing.horizon_t_s:
            return  # beyond the windows the context holds
        found = timing.results_on_ground(end)
        if found is None:
            if timing.horizon_t_s <= deadline:
                return  # no window known before the deadline, and none known after it
            text = (
                f"sol {sol}'s plan cannot build on this drive: no downlink window is "
                f"predicted between its end ({ctx.clock(end)}) and "
                f"{ctx.clock(timing.horizon_t_s)}, so its results reach the ground after the {due}"
            )
            self.warn(step, "restricted-sol", text)
            return
        sent, arrival, window = found
        if arrival <= deadline:
            return
        latency = (
            f" + {timing.relay_latency_s / 60.0:.0f} min relay latency"
            if window.kind == "relay"
            else ""
        )
        light_min = (arrival - sent - (timing.relay_latency_s if latency else 0.0)) / 60.0
        via = "relay pass" if window.kind == "relay" else "direct-to-Earth session"
        text = (
            f"sol {sol}'s plan cannot build on this drive: its results reach the ground at "
            f"{ctx.clock(arrival)} (sent in the {via} at {ctx.clock(sent)}{latency} + "
            f"{light_min:.1f} min light time), after the {due}"
        )
        self.warn(step, "restricted-sol", text)


def _hm(hours: float) -> str:
    minutes = round(hours * 60.0) % (24 * 60)
    return f"{minutes // 60:02d}:{minutes % 60:02d}"
