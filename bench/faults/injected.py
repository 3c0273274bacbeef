"""The injected-fault cases of ``roverops bench faults``: the bench acts as the test
conductor (``sim.faults``) and scores what the flight software made of the fault.

- **Gyro bias step**: 10 deg/h on the gyro about body z, then 20 min of driving (45 m at
  MER's 3.75 cm/s; a leg halted by fault protection cleared and driven on), then SUNCHECK
  (tolerance 2 deg). Started at 08:00 LMST at Gusev, so that
  the sun is low (about 20-35 deg up) when the check runs: a heading error moves the sun in
  the image by the error times the cosine of its elevation, and Suncheck sees only that
  (Ali et al. 2005 sec. 2.3.2). ``gyro_step_detected_pct``: Suncheck failed its tolerance;
  ``gyro_step_restored_pct``: SUNCHECK_SUNGAZE after it brought AQF Fine with the true
  attitude error inside the 3σ the rover then reports (2 deg less its predicted HGA margin).
- **Navcam failure** during a 3 m VO drive, with ``vo_fail=halt`` and ``vo_fail=continue``:
  ``navcam_fail_clean_pct``, each step's failure reported in an event, the drive halted
  (``vo_fail``) or completed as commanded, no exception.
- **Pancam dust** of optical depth 4, GET_COARSE_ATTITUDE: ``dust_sunfind_refusal_clean_pct``,
  the command fails with its reason, or succeeds with the true attitude error inside the
  reported 3σ; never a Coarse or Fine flag with a larger error.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Any

from sequences import commands as cmd
from sim.faults.records import GyroBias, NavcamFailure, PancamDust
from sim.loop.session import RoverSession

MORNING_GUSEV = datetime(2004, 4, 14, 13, 30, tzinfo=UTC)  # about 07:05 LMST at Gusev
DRIVE_20_MIN_M = 45.0  # 20 min at 3.75 cm/s
SUNCHECK_TOLERANCE_DEG = 2.0


def _fine(seed: int, start: datetime) -> RoverSession:
    s = RoverSession("gusev", seed, start)
    report = s.execute(cmd.GetFineAttitude())
    if report.status != "completed":
        raise RuntimeError(f"GET_FINE_ATTITUDE {report.status}: {report.reason}")
    return s


def _three_sigma_deg(s: RoverSession) -> float:
    """The attitude 3σ the rover reports now: 2 deg less its predicted HGA margin."""
    margin = s.downlinks[-1].hga_margin_predicted_deg
    return 2.0 - margin if math.isfinite(margin) else math.inf


def _drive(s: RoverSession, distance_m: float) -> None:
    """``distance_m`` by the rover's estimate, in legs of at most 15 m; a leg that fault
    protection halts (a bogie over a rock, say) is cleared and driven on, as the team would:
    the case is the gyro's, not the terrain's."""
    left = distance_m
    while left > 0.05:
        p0 = s.nate.p_s.copy()
        report = s.execute(cmd.DriveStraight(distance_m=min(15.0, left)))
        left -= float(math.hypot(*(s.nate.p_s - p0)[:2]))
        if report.status == "halted":
            s.execute(cmd.ClearMobilityFault())
        elif report.status != "completed":
            raise RuntimeError(f"drive {report.status}: {report.reason}")


def gyro_step_run(seed: int) -> dict[str, Any]:
    s = _fine(seed, MORNING_GUSEV)
    s.faults.add(GyroBias("z", 10.0), at_t_s=s.sim.t_s)
    _drive(s, DRIVE_20_MIN_M)
    check = s.execute(cmd.Suncheck(tolerance_deg=SUNCHECK_TOLERANCE_DEG))
    error_before = math.degrees(s.attitude_error_rad())
    restore = s.execute(cmd.SuncheckSungaze())
    error_after = math.degrees(s.attitude_error_rad())
    three_sigma = _three_sigma_deg(s)
    return {
        "detected": check.status == "failed",
        "error_at_check_deg": error_before,
        "restored": restore.status == "completed"
        and s.nate.aqf.paper_name == "Fine"
        and error_after <= three_sigma,
        "error_after_deg": error_after,
        "three_sigma_deg": three_sigma,
    }


def navcam_run(seed: int, policy: str) -> dict[str, Any]:
    s = _fine(seed, MORNING_GUSEV)
    s.faults.add(NavcamFailure(), at_t_s=s.sim.t_s)
    try:
        report = s.execute(cmd.DriveStraight(distance_m=3.0, vo=True, vo_fail=policy))
    except Exception as exc:  # an escape is what this case exists to catch
        return {"clean": False, "why": f"{type(exc).__name__}: {exc}"}
    failures = [e for e in report.events if e.kind == "vo" and "failed" in e.text]
    steps = report.details.get("vo_steps", 0)
    halt = report.details.get("halt") or {}
    if policy == "halt":
        clean = report.status == "halted" and halt.get("check") == "vo_fail"
        clean = clean and len(failures) >= 3  # the first pair and the steps until the halt
    else:
        clean = report.status == "completed" and len(failures) >= steps
    return {"clean": clean, "status": report.status, "failures": len(failures), "steps": steps}


def dust_run(seed: int) -> dict[str, Any]:
    s = RoverSession("gusev", seed, MORNING_GUSEV)
    s.faults.add(PancamDust(4.0), at_t_s=s.sim.t_s)
    report = s.execute(cmd.GetCoarseAttitude())
    aqf = s.nate.aqf.paper_name
    error = math.degrees(s.attitude_error_rad())
    three_sigma = _three_sigma_deg(s)
    if report.status == "failed":
        clean = bool(report.reason) and aqf not in ("Coarse", "Fine")
    else:
        clean = error <= three_sigma
    return {"clean": clean, "status": report.status, "aqf": aqf, "error_deg": error}
