"""The session's one command table (``sim.loop.handlers.HANDLERS``): every command of the
dictionary has its handler, and nothing else does."""

from __future__ import annotations

from sequences.commands import COMMANDS
from sim.loop.handlers import ACQUISITIONS, HANDLERS, acquisition


def test_every_command_of_the_dictionary_has_one_handler() -> None:
    assert set(HANDLERS) == set(COMMANDS.values())


def test_the_acquisitions_run_through_the_acquisition_handler() -> None:
    """SUNCHECK_SUNGAZE has its own, which names a failed Suncheck after running it."""
    assert {k for k, h in HANDLERS.items() if h is acquisition} == set(ACQUISITIONS) - {
        kind for kind in ACQUISITIONS if kind.name == "SUNCHECK_SUNGAZE"
    }
