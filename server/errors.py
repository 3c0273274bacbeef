"""The server's domain errors: what went wrong in the server's own terms, never in HTTP's.

Domain code (``server.state``, the alarm engine, the runtime's queue, the accounts) raises
these; ``server.api.deps.install_error_handlers`` maps each to its HTTP answer in one place
(404, 409, 422), so no module below ``server.api`` speaks HTTP.
"""

from __future__ import annotations


class DomainError(Exception):
    """A request the server's state cannot honour."""


class NotFoundError(DomainError, LookupError):
    """No such rover, record or channel (HTTP 404)."""


class UnknownRoverError(NotFoundError):
    """A rover this server does not run."""

    def __init__(self, name: str, known: list[str]) -> None:
        super().__init__(f"unknown rover {name!r}; known: {', '.join(known)}")
        self.name = name


class UnknownChannelError(NotFoundError, KeyError):
    """A channel with no alarm limits (a ``KeyError`` too, for the callers that look up)."""

    def __str__(self) -> str:  # KeyError's own quotes its message
        return str(self.args[0])


class ConflictError(DomainError):
    """A change the record's state does not allow now (HTTP 409); nothing changed."""


class InvalidError(DomainError, ValueError):
    """A value the request gave that cannot be (HTTP 422): ``loc`` says where in the request
    (FastAPI's validation-error ``loc``), ``kind`` what kind of problem."""

    loc: tuple[str | int, ...] = ("body",)
    kind: str = "value_error"
