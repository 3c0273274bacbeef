"""Planning across the light time (``sequences.comm_timing``) on a hand-made link: fixed
windows and a fixed light time give exact onboard and on-the-ground times; a time tag
before the sequence is onboard warns with its line, a drive whose results miss the
planning time warns ``restricted-sol``, one followed by an early pass does not."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from sequences.comm_timing import (
    UPLINK_HEADER_BITS,
    CommTiming,
    LinkWindow,
    radiation,
    uplink_bits,
)
from sequences.language import parse
from sequences.validate import CODES, ValidationContext, ValidationResult, validate

SOL_S = 88775.244
LIGHT_S = 600.0  # ten minutes each way, the same all along (one sample)
LATENCY_S = 1800.0


def at(sol: int, lmst_h: float) -> float:
    """``t_s`` of ``lmst_h`` on ``sol`` of the hand-made clock (sols from t_s = 0)."""
    return (sol + lmst_h / 24.0) * SOL_S


UPLINK = LinkWindow("uplink", at(286, 9.0), at(286, 10.0), 2000.0)
EARLY_PASS = LinkWindow("relay", at(286, 15.0), at(286, 15.0 + 10 / 60), 128_000.0)
LAST_PASS = LinkWindow("relay", at(286, 20.0), at(286, 20.0 + 10 / 60), 128_000.0)
NEXT_UPLINK = LinkWindow("uplink", at(287, 9.0), at(287, 10.0), 2000.0)


def timing(**changes: Any) -> CommTiming:
    values: dict[str, Any] = {
        "uplink_from_t_s": at(286, 8.0),
        "uplink_until_t_s": at(296, 8.0),
        "windows": (UPLINK, EARLY_PASS, LAST_PASS, NEXT_UPLINK),
        "horizon_t_s": at(289, 8.0),
        "relay_latency_s": LATENCY_S,
        "planning_lmst_h": 18.0,
        "light_t_s": (at(286, 8.0),),
        "uplink_light_s": (LIGHT_S,),
        "downlink_light_s": (LIGHT_S,),
    }
    values.update(changes)
    return CommTiming(**values)


def context(comm: CommTiming | None = None, **changes: Any) -> ValidationContext:
    """Sol 286 08:00 on the hand-made clock, Fine, the link's ``comm``."""
    values: dict[str, Any] = {
        "start_t_s": at(286, 8.0),
        "lmst_h": lambda t: (t % SOL_S) / SOL_S * 24.0,
        "sol": lambda t: int(t // SOL_S),
        "t_s_for": lambda sol, h: at(sol, h),
        "earth_elevation_deg": lambda t: 20.0,
        "aqf": "Fine",
        "comm": comm,
    }
    values.update(changes)
    return ValidationContext(**values)


def codes(result: ValidationResult) -> list[tuple[int, int, str]]:
    return [(d.line, d.column, d.code) for d in result.warnings]


def onboard_of(text: str, comm: CommTiming) -> float:
    """The onboard time the walk predicts for ``text``: radiated from 09:00, 10 min of light."""
    when = comm.onboard(uplink_bits(parse(text)))
    assert when is not None
    return when[1]


def test_the_codes_are_warnings() -> None:
    for code in ("before-onboard", "no-uplink", "restricted-sol"):
        assert CODES[code] == "warning"


def test_the_onboard_time_is_the_radiation_end_plus_the_light_time() -> None:
    text = "SEQUENCE s\nNADIR_UPDATE\n"
    bits = uplink_bits(parse(text))
    assert bits == UPLINK_HEADER_BITS + 8 * len(text.encode())  # its text form, as written
    comm = timing()
    radiated, onboard = comm.onboard(bits) or (0.0, 0.0)
    assert radiated == UPLINK.start_t_s + bits / 2000.0  # the window opens after the moment
    assert onboard == pytest.approx(radiated + LIGHT_S, abs=1e-9)
    # a ground moment inside the window radiates at once; uplinks waiting push it on
    inside = timing(uplink_from_t_s=at(286, 9.5))
    assert inside.onboard(bits) == pytest.approx(
        (at(286, 9.5) + bits / 2000, at(286, 9.5) + bits / 2000 + LIGHT_S)
    )
    # a sequence the window cannot hold whole waits for a longer one, or never goes
    assert radiation((UPLINK,), 7_500_000, 0.0, 1e12) is None
    assert comm.onboard(7_500_000) is None


def test_the_light_time_is_interpolated_between_samples() -> None:
    comm = timing(light_t_s=(0.0, 1000.0), uplink_light_s=(600.0, 601.0),
                  downlink_light_s=(600.0, 602.0))  # fmt: skip
    assert comm.downlink_arrival_t_s(500.0) == pytest.approx(500.0 + 601.0)
    assert comm.downlink_arrival_t_s(5000.0) == pytest.approx(5000.0 + 602.0)  # the end's
    # t_a = t_r + τ(t_a): 0.001 s/s of change
    t_a = comm.uplink_arrival_t_s(0.0)
    assert t_a == pytest.approx(600.0 + 0.001 * t_a, abs=1e-9)


def test_the_walk_starts_once_the_sequence_is_onboard() -> None:
    """An untagged drive starts when the sequence is onboard (09:10), not at the
    validation moment (08:00): its time-of-day limit at 09:05 is then past."""
    text = "DRIVE_STRAIGHT distance_m=3.75 lmst_limit_h=9.18\n"
    assert codes(validate(text, context())) == []  # instant: 08:00 to 08:01:40
    assert codes(validate(text, context(timing()))) == [(1, 1, "lmst-limit")]


def test_a_tagged_step_before_onboard_warns_with_its_line() -> None:
    comm = timing()
    text = (
        "SEQUENCE early\n"
        "NADIR_CHECK\n"
        "@ sol 286 09:05 LMST NADIR_CHECK\n"  # before 09:10 onboard: late
        "@ sol 286 09:30 LMST NADIR_CHECK\n"  # after: as tagged
    )
    result = validate(text, context(comm))
    assert codes(result) == [(3, 1, "before-onboard")]  # not tag-passed as well
    message = result.warnings[0].message
    onboard = context().clock(onboard_of(text, comm))
    assert onboard == "sol 286 09:10 LMST"
    assert "sol 286 09:05 LMST comes before the sequence can be onboard" in message
    assert f"({onboard}: radiated by sol 286 09:00 LMST, then 10.0 min of light time)" in message
    assert message.endswith("it starts late, at sol 286 09:10 LMST")
    # in instant mode the same sequence is onboard at 08:00: nothing to say
    assert codes(validate(text, context())) == []


def test_an_lmst_tag_before_onboard_waits_for_the_next_sol() -> None:
    text = "@ 09:05 LMST NADIR_CHECK\n@ 20:00 LMST HGA_PASS\n"
    result = validate(text, context(timing()))
    assert codes(result) == [(1, 1, "before-onboard")]
    message = result.warnings[0].message
    assert message.startswith("09:05 LMST of sol 286 comes before the sequence can be onboard")
    assert message.endswith("it waits until sol 287 09:05 LMST")
    # read from the validation moment, a time already past then (07:00) is meant for the
    # next sol: no warning
    assert codes(validate("@ 07:00 LMST NADIR_UPDATE\n", context(timing()))) == []
    # an LMST tag after a step that ends after it is the old warning, not this one
    later = "WAIT duration_s=3600\n@ 09:30 LMST NADIR_UPDATE\n"
    assert codes(validate(later, context(timing()))) == [(2, 1, "tag-next-sol")]


def test_a_drive_followed_by_an_early_pass_does_not_warn() -> None:
    comm = timing()
    end = onboard_of("DRIVE_STRAIGHT distance_m=3.75\n", comm) + 100.0
    # results: the 15:00 pass, 30 min at the orbiter, 10 min of light: 15:39 LMST
    sent, arrival, window = comm.results_on_ground(end) or (0.0, 0.0, None)
    assert (sent, window) == (EARLY_PASS.start_t_s, EARLY_PASS)
    assert arrival == pytest.approx(EARLY_PASS.start_t_s + LATENCY_S + LIGHT_S, abs=1e-9)
    assert codes(validate("DRIVE_STRAIGHT distance_m=3.75\n", context(comm))) == []
    # a drive ending while the pass is up goes down at once
    during = at(286, 15.05)
    assert comm.results_on_ground(during)[:2] == pytest.approx(  # type: ignore[index]
        (during, during + LATENCY_S + LIGHT_S)
    )
    assert codes(validate("@ 15:02 LMST DRIVE_STRAIGHT distance_m=0.75\n", context(comm))) == []


def test_a_drive_after_the_last_pass_before_the_deadline_is_a_restricted_sol() -> None:
    text = "NADIR_CHECK\n@ 15:30 LMST DRIVE_STRAIGHT distance_m=3.75\n"
    result = validate(text, context(timing()))
    assert codes(result) == [(2, 14, "restricted-sol")]
    assert result.warnings[0].message == (
        "sol 286's plan cannot build on this drive: its results reach the ground at "
        "sol 286 20:39 LMST (sent in the relay pass at sol 286 20:00 LMST + 30 min relay "
        "latency + 10.0 min light time), after the 18:00 LMST planning time (restricted sol)"
    )
    # a drive ending after the planning time is always too late, whatever the pass
    late = validate("@ 18:30 LMST TURN_IN_PLACE angle_deg=10\n", context(timing()))
    assert codes(late) == [(1, 14, "restricted-sol")]
    # a direct-to-Earth session open at the drive's end: no relay latency
    dte = LinkWindow("dte", at(286, 15.5), at(286, 17.0), 10_000.0)
    windows = tuple(sorted((*timing().windows, dte), key=lambda w: w.start_t_s))
    assert codes(validate(text, context(timing(windows=windows)))) == []
    # the deadline is the planning LMST the plan says
    assert codes(validate(text, context(timing(planning_lmst_h=21.0)))) == []


def test_a_drive_with_no_pass_known_after_it() -> None:
    windows = (UPLINK, NEXT_UPLINK)
    text = "@ 12:00 LMST DRIVE_STRAIGHT distance_m=3.75\n"
    result = validate(text, context(timing(windows=windows)))
    assert codes(result) == [(1, 14, "restricted-sol")]
    assert "no downlink window is predicted between its end" in result.warnings[0].message
    # the windows known stop before the deadline: nothing can be said
    short = timing(windows=windows, horizon_t_s=at(286, 17.0))
    assert codes(validate(text, context(short))) == []
    # past the horizon: not checked
    far = "@ sol 290 12:00 LMST DRIVE_STRAIGHT distance_m=3.75\n"
    assert codes(validate(far, context(timing()))) == []


def test_no_uplink_window_says_so_and_predicts_from_now() -> None:
    tiny = LinkWindow("uplink", at(286, 9.0), at(286, 9.0) + 0.01, 2000.0)
    comm = timing(windows=(tiny, EARLY_PASS))
    text = "DRIVE_STRAIGHT distance_m=3.75 lmst_limit_h=9.18\n@ sol 286 08:30 LMST NADIR_UPDATE\n"
    result = validate(text, context(comm))
    assert codes(result) == [(1, 1, "no-uplink")]  # from 08:00: no lmst-limit, no tag late
    message = result.warnings[0].message
    assert message.startswith("no uplink window before sol 296 08:00 LMST can radiate this")
    assert "as if it were onboard now" in message
    queued = dataclasses.replace(timing(), uplink_from_t_s=float("inf"))
    assert (
        "after the uplinks already waiting" in validate(text, context(queued)).warnings[0].message
    )


def test_instant_mode_is_unchanged() -> None:
    text = (
        "@ sol 286 08:30 LMST NADIR_CHECK\n"
        "@ 15:30 LMST DRIVE_STRAIGHT distance_m=3.75\n"
        "@ 18:30 LMST TURN_IN_PLACE angle_deg=10\n"
    )
    assert codes(validate(text, context())) == []
    assert [c for _, _, c in codes(validate(text, context(timing())))] == [
        "before-onboard",
        "restricted-sol",
        "restricted-sol",
    ]


def test_the_timing_refuses_malformed_samples() -> None:
    with pytest.raises(ValueError, match="light_t_s"):
        timing(light_t_s=(), uplink_light_s=(), downlink_light_s=())
    with pytest.raises(ValueError, match="ascending"):
        timing(light_t_s=(2.0, 1.0), uplink_light_s=(1.0, 1.0), downlink_light_s=(1.0, 1.0))
    with pytest.raises(ValueError, match="sorted"):
        timing(windows=(LAST_PASS, UPLINK))
