"""Where the store's database lives and how its threads share it: the embedded SQLite
file of a data directory, and the one connection of an in-memory database."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

from sqlalchemy.pool import StaticPool


class OneThreadAtATimePool(StaticPool):
    """The one connection of an in-memory SQLite database, which every thread shares, held
    by one thread at a time: two threads' transactions on it would interleave (a read's
    rollback on return undid the writer's uncommitted frames)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._holder = threading.RLock()

    def _do_get(self) -> Any:
        self._holder.acquire()
        return super()._do_get()

    def _do_return_conn(self, record: Any) -> None:
        super()._do_return_conn(record)
        self._holder.release()


def data_dir_url(data_dir: Path) -> str:
    """The embedded SQLite database under ``data_dir`` (created if missing)."""
    data_dir.mkdir(parents=True, exist_ok=True)
    return f"sqlite:///{(data_dir / 'roverops.db').resolve()}"
