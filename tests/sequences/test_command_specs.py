"""The ranges ``GET /api/commands`` publishes are the ranges validation enforces.

For every command and every numeric argument in the published dictionary: a closed lower
bound and the upper bound are accepted, an open lower bound is refused and the next float
above it accepted, and the next float outside each bound is refused with a ``ValueError``
naming the argument and quoting the published range. Each value goes through the command's
constructor and through the JSON sequence parser the server's command route uses. The other
arguments are left to their defaults or take the valid values in ``COMPANIONS``.

``range_problems`` returns what disagrees instead of asserting, so a test can show that it
notices a published range drifting from the validation (a wider maximum, a closed bound
published as open).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any, ClassVar

import pytest
from fastapi.testclient import TestClient

from sequences import commands as cmd
from sequences.language import parse_json
from server.app import ServerConfig, create_app, data_dir_url

# Valid values for the required arguments that are not under test, chosen so that no rule
# across arguments fires at either bound of the one under test: DRIVE_ARC's 1 m radius keeps
# a 360 deg arc at 6.3 m, its 1 deg angle keeps a 1000 m radius arc at 17.5 m (limit 100 m).
# The drives' VO pointing (vo_az_deg, vo_el_deg) needs vo=on.
COMPANIONS: dict[str, dict[str, Any]] = {
    "DRIVE_ARC": {"radius_m": 1.0, "angle_deg": 1.0, "vo": True},
    "DRIVE_TO": {"x_m": 3.0, "y_m": 4.0, "vo": True},
    "DRIVE_STRAIGHT": {"distance_m": 1.0, "vo": True},
    "TURN_IN_PLACE": {"angle_deg": 10.0, "vo": True},
    # a circle needs its three numbers together
    "KEEPOUT_ADD": {"zone": "rock", "x_m": 1.0, "y_m": 2.0, "radius_m": 0.5},
}


@pytest.fixture(scope="module")
def dictionary(tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, Any]]:
    """The dictionary as the server publishes it (no lifespan needed for this route)."""
    url = data_dir_url(tmp_path_factory.mktemp("specs"))
    app = create_app(ServerConfig(database_url=url, operator_token="unused-token"))
    response = TestClient(app).get("/api/commands")
    assert response.status_code == 200
    body: list[dict[str, Any]] = response.json()
    return body


def _arguments(command: str, args: list[dict[str, Any]], arg: str, value: float) -> dict[str, Any]:
    """``arg=value`` plus every other required argument from ``COMPANIONS``."""
    out = {arg: value}
    for other in args:
        companion = other["name"] in COMPANIONS.get(command, {})
        if other["name"] != arg and (other["required"] or companion):
            out[other["name"]] = COMPANIONS[command][other["name"]]
    return out


def _refusal(command: str, arguments: dict[str, Any]) -> list[str]:
    """The messages with which the constructor and the JSON parser refuse the command
    (empty when both accept it; one message from each that refuses)."""
    messages = []
    try:
        cmd.COMMANDS[command](**arguments)
    except ValueError as exc:
        messages.append(str(exc))
    parsed = parse_json({"name": "specs", "steps": [{"command": command, "args": arguments}]})
    messages += [d.message.removeprefix("steps[0].args.") for d in parsed.diagnostics]
    return messages


def _cases(arg: dict[str, Any]) -> list[tuple[float, bool]]:
    """``(value, accepted)`` at and just beyond the published bounds."""
    lo, hi = float(arg["min"]), float(arg["max"])
    below, above = math.nextafter(lo, -math.inf), math.nextafter(hi, math.inf)
    if arg["min_exclusive"]:
        lower = [(lo, False), (math.nextafter(lo, math.inf), True)]
    else:
        lower = [(lo, True), (below, False)]
    return [*lower, (hi, True), (above, False)]


def range_problems(dictionary: list[dict[str, Any]]) -> list[str]:
    """Every disagreement between a published numeric range and the validation."""
    problems = []
    for entry in dictionary:
        command, args = entry["command"], entry["args"]
        for arg in (a for a in args if a["type"] == "number"):
            where = f"{command}.{arg['name']}"
            for value, accepted in _cases(arg):
                messages = _refusal(command, _arguments(command, args, arg["name"], value))
                if accepted and messages:
                    problems.append(f"{where}={value!r} is published valid, refused: {messages}")
                expected = f"{arg['name']}: must be in {arg['range']}, got "
                if not accepted and (len(messages) != 2 or not all(
                    m.startswith(expected) for m in messages
                )):  # fmt: skip
                    problems.append(
                        f"{where}={value!r} is published invalid; want {expected!r}, got {messages}"
                    )
    return problems


def test_every_published_range_is_the_one_validation_enforces(
    dictionary: list[dict[str, Any]],
) -> None:
    numeric = [
        (c["command"], a["name"]) for c in dictionary for a in c["args"] if a["type"] == "number"
    ]
    assert len(numeric) == 36  # every numeric argument of the dictionary is covered
    assert range_problems(dictionary) == []


def test_a_published_range_that_drifts_from_the_validation_is_noticed(
    dictionary: list[dict[str, Any]],
) -> None:
    drifted = copy.deepcopy(dictionary)
    arguments = {(c["command"], a["name"]): a for c in drifted for a in c["args"]}
    arguments[("DRIVE_STRAIGHT", "distance_m")]["max"] = 150.0  # validation stops at 100 m
    arguments[("TURN_IN_PLACE", "angle_deg")]["min_exclusive"] = True  # validation: closed
    arguments[("HGA_PASS", "duration_min")]["range"] = "(0, 60] min"  # the text users see
    problems = range_problems(drifted)
    assert sorted(p.split(" is ")[0] for p in problems) == [
        "DRIVE_STRAIGHT.distance_m=150.0",  # published valid, refused
        "HGA_PASS.duration_min=0.0",  # refused, but quoting another range than published
        "HGA_PASS.duration_min=120.00000000000001",
        "TURN_IN_PLACE.angle_deg=-360.0",  # published refused, accepted
    ]


def test_every_argument_is_published_with_the_spec_validation_uses(
    dictionary: list[dict[str, Any]],
) -> None:
    """Non-numeric arguments say their kind; numbers their unit (a spec is missing for
    no argument: the module refuses to load otherwise)."""
    for entry in dictionary:
        kind = cmd.COMMANDS[entry["command"]]
        assert [a["name"] for a in entry["args"]] == list(kind.specs)
        for arg in entry["args"]:
            spec = kind.specs[arg["name"]]
            assert arg["type"] == spec.kind
            assert (arg["unit"] is not None) == (spec.kind == "number")
            # a unit in the name (docs/CONVENTIONS.md) is the unit published
            if spec.kind == "number":
                assert arg["name"].endswith(f"_{arg['unit']}")


def test_a_malformed_spec_or_a_command_without_specs_is_refused() -> None:
    with pytest.raises(TypeError, match="lo, hi and a unit"):
        cmd.ArgSpec("number", "m")
    with pytest.raises(TypeError, match="lo, hi and a unit"):
        cmd.ArgSpec("boolean", lo=0.0, hi=1.0)

    @dataclass(frozen=True)
    class Unspecified(cmd.Command):
        name: ClassVar[str] = "UNSPECIFIED"
        distance_m: float

    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(cmd.COMMANDS, Unspecified.name, Unspecified)
        with pytest.raises(TypeError, match=r"Unspecified.specs: \[\], arguments \['distance_m'\]"):
            cmd._check_specs_match_arguments()


def test_companion_values_are_valid_on_their_own() -> None:
    for command, arguments in COMPANIONS.items():
        assert _refusal(command, arguments) == []
