"""The typed records the server hands to storage.

``CommandRecord`` is one executed (or refused) command as a rover runtime reports it
(``server.sinks.RuntimeListener.command_reported``): the server stores it
(``BatchWriter.command``) and announces it on the live timeline. Its fields are the columns
of the ``commands`` table, so a report and its stored row hold the same figures.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class CommandRecord:
    """A command's execution: ``sequence_id`` and ``step_index`` name its step (``None``
    for a command that is in no sequence), ``command`` is its text, ``status``
    ``completed``, ``refused`` or ``failed`` (``reason`` says why), ``start_t_s`` and
    ``end_t_s`` its span on the rover's clock (TT s from J2000), ``events`` the texts of
    the rover's events while it ran."""

    sequence_id: int | None
    step_index: int | None
    command: str
    status: str
    reason: str | None
    start_t_s: float
    end_t_s: float
    events: tuple[str, ...] = field(default=())
