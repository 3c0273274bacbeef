"""How ``roverops run`` prints a scenario's summary for a reader: one ``key: figure unit``
line each, vectors by axis, the commands one a line with their events, and no Python
repr. The keys are the summary's own (``--json``), so a line can be found in either.

The unit comes from the key's suffix (``_m``, ``_deg``, ``_deg_per_h``: the project's names
carry it, docs/CONVENTIONS.md), except for the figures whose name carries a frame and
no unit because they are plain SI (``p_s_est``: metres in Site), listed in ``UNITS``.
"""

from __future__ import annotations

from typing import Any

from cli.output import fmt, print_result

# Figures in SI whose name ends in a frame, not a unit, and the commanded amounts.
UNITS = {
    "final_p_s": "m",
    "p_s_est": "m",
    "p_s_true": "m",
    "idle_s_jumped": "s",
    "rest": "s",
    "straight": "m",
    "turn": "deg",
    "sapp": "m",  # the drive of GetFineAttitude, a drive, an HGA pass
}
# The longest suffix first: "_deg_per_h" before "_h", "_mm" before "_m".
SUFFIX_UNITS = (
    ("_pct_of_distance", "% of the distance"),
    ("_deg_per_h", "deg_per_h"),
    ("_pct", "%"),
    ("_mm", "mm"),
    ("_deg", "deg"),
    ("_m", "m"),
    ("_s", "s"),
    ("_h", "h"),
)
SHOWN = {"deg": "°", "deg_per_h": "°/h"}
AXES = ("x", "y", "z")


def unit_of(key: str) -> str:
    """The unit of figure ``key`` as its name gives it ('' for a count or a name).

    >>> unit_of("max_wheel_gap_mm"), unit_of("gyro_rate_b_deg_per_h"), unit_of("p_s_est")
    ('mm', 'deg_per_h', 'm')
    """
    if key in UNITS:
        return UNITS[key]
    return next((unit for suffix, unit in SUFFIX_UNITS if key.endswith(suffix)), "")


def with_unit(value: Any, unit: str) -> str:
    """A figure as text: a number and its unit, a vector by axis, a missing one as such.

    >>> with_unit([1.0, -2.0, 0.5], "m"), with_unit(3.5, "deg"), with_unit(None, "deg")
    ('x 1 m, y -2 m, z 0.5 m', '3.5°', 'not estimated')
    """
    if value is None:
        return "not estimated"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (list, tuple)):
        labels = AXES if len(value) == len(AXES) else [str(i) for i in range(len(value))]
        pairs = zip(labels, value, strict=True)
        return ", ".join(f"{label} {with_unit(v, unit)}" for label, v in pairs)
    if not isinstance(value, (int, float)) or not unit:
        return fmt(value)
    shown = SHOWN.get(unit, unit)
    return f"{fmt(float(value))}{'' if shown in SHOWN.values() else ' '}{shown}"


def _command_lines(reports: list[dict[str, Any]]) -> list[str]:
    """Each command report: its text, status and simulated duration, then its events."""
    lines = []
    for report in reports:
        ended = f"{report['status']} in {with_unit(report['duration_s'], 's')}"
        if report.get("reason"):
            ended += f" ({report['reason']})"
        lines.append(f"  {report['command']}: {ended}")
        lines += [f"    {e['kind']} ({e['severity']}): {e['text']}" for e in report["events"]]
    return lines


def run_lines(summary: dict[str, Any]) -> list[str]:
    """The summary of ``sim.scenarios.headless.run_scenario`` as text lines."""
    lines = []
    for key, value in summary.items():
        if key == "command":  # {kind: amount}, one entry
            ((kind, amount),) = value.items()
            lines.append(f"command: {kind} {with_unit(amount, unit_of(kind))}")
        elif key == "commands":
            lines += ["commands:", *_command_lines(value)]
        elif key == "estimators":
            lines.append("estimators:")
            for name, errors in value.items():
                lines.append(f"  {name}:")
                lines += [f"    {k}: {with_unit(v, unit_of(k))}" for k, v in errors.items()]
        else:
            lines.append(f"{key}: {with_unit(value, unit_of(key))}")
    return lines


def print_run(result: dict[str, Any], as_json: bool) -> None:
    """``roverops run``'s printer: the summary as JSON, or as ``run_lines``."""
    if as_json:
        print_result(result, as_json)
        return
    print("\n".join(run_lines(result)))
