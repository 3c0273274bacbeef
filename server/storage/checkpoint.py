"""A rover's checkpoint as bytes: the runtime's state (``RoverRuntime.checkpoint_state``),
plain data only, with its format version.

Format 2 (this one): UTF-8 JSON, ``{"format": 2, "rover": name, "state": {...}}``, compressed
with zlib behind the byte ``Z`` when it is over ``COMPRESS_OVER_BYTES`` (across light time a
rover's store holds thousands of frames: the JSON shrinks about fivefold). A numpy
array is ``{"__ndarray__": base64 of its bytes (C order), "dtype": ..., "shape": [...]}``, so
the numbers come back bit for bit; NaN and infinities are JSON's common extension
(``NaN``, ``Infinity``). Format 1 was a pickle of the whole runtime's objects: it cannot
survive a refactor and is refused, as is a future format or a blob that is not a checkpoint
(``CheckpointFormatError``, whose message says that the rover starts fresh).
"""

from __future__ import annotations

import base64
import json
import zlib
from collections.abc import Mapping
from typing import Any

import numpy as np

CHECKPOINT_FORMAT = 2
COMPRESS_OVER_BYTES = 65_536
_ZLIB_MAGIC = b"Z"  # JSON starts with "{": a compressed checkpoint with this
_PICKLE_MAGIC = b"\x80"  # every pickle protocol since 2 starts with PROTO


class CheckpointFormatError(ValueError):
    """A checkpoint this version cannot load; the message says why and what happens."""


def _default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        data = np.ascontiguousarray(value)
        return {
            "__ndarray__": base64.b64encode(data.tobytes()).decode("ascii"),
            "dtype": data.dtype.str,
            "shape": list(data.shape),
        }
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not plain data: {type(value).__name__}")


def _array(obj: dict[str, Any]) -> Any:
    if "__ndarray__" in obj:
        raw = base64.b64decode(obj["__ndarray__"])
        return np.frombuffer(raw, dtype=np.dtype(obj["dtype"])).reshape(obj["shape"]).copy()
    return obj


def encode(rover: str, state: Mapping[str, Any]) -> bytes:
    """``state`` (plain data: None, bool, int, float, str, lists, str-keyed dicts, numpy
    arrays) as a checkpoint of ``rover``. Raises ``TypeError`` for anything else."""
    doc = {"format": CHECKPOINT_FORMAT, "rover": rover, "state": state}
    blob = json.dumps(doc, default=_default, separators=(",", ":")).encode("utf-8")
    if len(blob) > COMPRESS_OVER_BYTES:
        return _ZLIB_MAGIC + zlib.compress(blob, 1)
    return blob


def decode(rover: str, blob: bytes) -> dict[str, Any]:
    """The state of a checkpoint of ``rover`` (``encode``); ``CheckpointFormatError`` for a
    blob of another format or none."""
    fresh = "the rover starts fresh, its stored telemetry stays"
    if blob[:1] == _PICKLE_MAGIC:
        raise CheckpointFormatError(
            f"checkpoint of rover {rover} was written in format 1 (a pickle of an older "
            f"roverops); {fresh}"
        )
    try:
        if blob[:1] == _ZLIB_MAGIC:
            blob = zlib.decompress(blob[1:])
        doc = json.loads(blob.decode("utf-8"), object_hook=_array)
        version = doc["format"] if isinstance(doc, dict) else None
    except (UnicodeDecodeError, ValueError, KeyError, zlib.error) as exc:
        raise CheckpointFormatError(
            f"checkpoint of rover {rover} is not a checkpoint this roverops can read ({exc}); "
            f"{fresh}"
        ) from exc
    if version != CHECKPOINT_FORMAT or not isinstance(doc.get("state"), dict):
        raise CheckpointFormatError(
            f"checkpoint of rover {rover} was written in format {version!r}, this roverops "
            f"reads format {CHECKPOINT_FORMAT}; {fresh}"
        )
    state: dict[str, Any] = doc["state"]
    return state
