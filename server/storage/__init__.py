"""Storage of the operations server: sequences, commands, events, telemetry and checkpoints.

One SQLAlchemy 2 (Core) layer over any database URL, so that the embedded default (SQLite,
a file under the data directory) and a shared server (PostgreSQL) behave the same and run
the same tests. ``Store`` is the synchronous API the request handlers call; ``BatchWriter``
takes the high-rate writes off the simulation threads (docs/DESIGN.md: "server stores frames
(batched)") and commits them together at least once per ``interval_s`` of wall time, so a
server killed with SIGKILL loses at most the writes of the last interval (issue 4, item 5).

Choices worth knowing:

- SQLite runs in WAL mode (readers never block the writer thread and the writer never
  blocks the request threads), with foreign keys on and ``synchronous=NORMAL``: a committed
  transaction survives the process being killed; only a power cut may lose the last ones.
- A telemetry frame is two rows: its downlink record in ``frames`` and its truth record in
  ``truth_frames`` (docs/DESIGN.md, "Two records"), each number of the record in a column of
  its own, generated from the record's type (``server.storage.columns``: a list field one
  column per component, named as the CSV names it), the rest (events, the side estimators,
  the command, the modes) as JSON beside it. Every ``CHUNK_FRAMES`` rows of a rover, their
  numbers are packed too, a float64 array per channel and chunk (``server.storage.chunks``),
  so a channel query (``Store.channel``) reads its chunks' arrays and the few rows after the
  last chunk; a field added to a record gets its column when a database is opened, and a
  database without chunks has them packed then. A database of the release before (whole
  merged frames as JSON) is split into the two records in place when it is opened
  (``server.storage.migrate``).
- JSON has no NaN or infinity (PostgreSQL's ``json`` rejects them) while frames carry NaN
  for "no value" (a tilt before the first estimate), so non-finite floats are stored as
  ``null`` on every database and read back as ``None``.
- Timestamps are wall-clock UTC, returned as ISO 8601 strings with ``+00:00``.
- A step of a sequence has one command row, whatever the restarts (issue 13, defect 8): a
  server killed after a step's row was stored but before a checkpoint after that step runs
  the step again from its checkpoint, and recording it again updates the row and counts
  the re-run (``reruns``). The rule lives in the write path, not in a unique index, so a
  database that already holds such duplicates opens as before.
- Events (``estimation.events``) are stored with their kind and severity; those stored
  before events had them (as a column or inside a stored frame) read back as kind
  ``unknown``, severity ``info`` (``event_dict``).
- The schema grows in place: opening a database adds the columns and indexes this version
  declares and it lacks (``upgrade_schema``), so a database of an older version keeps
  working; a column added this way must be nullable or have a ``server_default``.

>>> store = Store("sqlite://")
>>> planted = {"text": "Site 1 planted", "kind": "site", "severity": "info"}
>>> store.add_events("spirit", [(10.0, planted)])
>>> store.events("spirit", 0.0, 20.0)
[{'t_s': 10.0, 'text': 'Site 1 planted', 'kind': 'site', 'severity': 'info'}]
>>> store.close()
"""

from server.storage.engine import data_dir_url
from server.storage.records import CommandRecord
from server.storage.schema import (
    LEGACY_KIND,
    LEGACY_SEVERITY,
    alarm_limits,
    alarms_table,
    api_tokens,
    audit_log,
    checkpoints,
    commands,
    event_dict,
    events,
    frames_table,
    metadata,
    sequences,
    users,
)
from server.storage.store import Store
from server.storage.writer import BatchWriter

__all__ = [
    "LEGACY_KIND",
    "LEGACY_SEVERITY",
    "BatchWriter",
    "CommandRecord",
    "Store",
    "alarm_limits",
    "alarms_table",
    "api_tokens",
    "audit_log",
    "checkpoints",
    "commands",
    "data_dir_url",
    "event_dict",
    "events",
    "frames_table",
    "metadata",
    "sequences",
    "users",
]
