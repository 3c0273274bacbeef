"""The images the rover sent, stored and read: each stored once, when it arrives.

An image product (``sim.loop.images.ImageDict``) reaches storage with its batch
(``server.sinks.StorageSink``, ``server.storage.writer.BatchWriter.images``). Its two 8-bit
images are encoded to PNG there, once (``cv2.imencode``: lossless, so the ground's pixels
are the ones the rover sent), and the PNG bytes are what the API serves, never rendered
again. A rover's image is one moment and kind (the table's unique index): one delivered
again (a restart across light time) is not stored twice.

The reads: ``list_images`` (metadata, filtered by time and kind, paged), ``image_detail``
(metadata and a VO pair's features), ``image_png`` (the stored bytes), and for the ground's
terrain map ``stereo_pairs`` (the images decoded, with their metadata: where the rover
believed it was, the mast's pointing, the rig). Every read commits the writes queued before
it first (``Store.commit_queued_with``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import and_, func, insert, select
from sqlalchemy.engine import Connection

from server.storage.schema import images_table

if TYPE_CHECKING:  # types only: storage loads without the simulator (roverops users)
    from server.storage.store import Store
    from sim.loop.images import ImageDict

# a writer's queued images: (rover, image records, received_t_s)
ImageRows = tuple[str, Sequence["ImageDict"], float | None]
Side = Literal["left", "right"]
SIDES: tuple[Side, ...] = ("left", "right")
_METADATA = ("f_px", "baseline_m", "mast_az_deg", "mast_el_deg", "site_index", "p_s_est",
             "p_mission_est", "q_b_ll_est", "vo")  # fmt: skip
_LISTED = (
    images_table.c.id,
    images_table.c.t_s,
    images_table.c.kind,
    images_table.c.width_px,
    images_table.c.height_px,
    images_table.c.received_t_s,
    images_table.c.meta,
)


def encode_png(image: NDArray[np.uint8]) -> bytes:
    """A 2-D 8-bit image as PNG bytes (lossless)."""
    array = np.ascontiguousarray(image)
    if array.ndim != 2 or array.dtype != np.uint8:
        raise ValueError(f"an image must be 2-D uint8, got {array.dtype} {array.shape}")
    import cv2  # here: the storage is also the user commands', which need no OpenCV

    ok, encoded = cv2.imencode(".png", array)
    if not ok:
        raise ValueError("PNG encoding failed")
    return bytes(encoded.tobytes())


def decode_png(data: bytes) -> NDArray[np.uint8]:
    """PNG bytes back as the 2-D 8-bit image they encode."""
    import cv2  # as encode_png

    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_UNCHANGED)
    if image is None or image.ndim != 2:
        raise ValueError("not a stored grey-level PNG")
    return np.asarray(image, dtype=np.uint8)


def image_row(rover: str, record: ImageDict, received_t_s: float | None) -> dict[str, Any]:
    """The row of one image: its PNGs encoded here, once."""
    return {
        "rover": rover,
        "t_s": float(record["t_s"]),
        "kind": str(record["kind"]),
        "width_px": int(record["width_px"]),
        "height_px": int(record["height_px"]),
        "received_t_s": received_t_s,
        "meta": {k: record[k] for k in _METADATA},  # type: ignore[literal-required]
        "features": record["features"],
        "left_png": encode_png(record["left"]),
        "right_png": encode_png(record["right"]),
    }


def insert_images(conn: Connection, rows: Sequence[ImageRows]) -> None:
    """Store the images of ``rows`` that are not stored yet (module docstring)."""
    seen: set[tuple[str, float, str]] = set()
    for rover, records, received in rows:
        for record in records:
            key = (rover, float(record["t_s"]), str(record["kind"]))
            where = and_(
                images_table.c.rover == rover,
                images_table.c.t_s == key[1],
                images_table.c.kind == key[2],
            )
            if key in seen or conn.execute(select(images_table.c.id).where(where)).first():
                continue
            seen.add(key)
            conn.execute(insert(images_table), [image_row(rover, record, received)])


def _listed(row: Mapping[Any, Any]) -> dict[str, Any]:
    return {
        "id": int(row["id"]),
        "t_s": float(row["t_s"]),
        "kind": str(row["kind"]),
        "width_px": int(row["width_px"]),
        "height_px": int(row["height_px"]),
        "received_t_s": row["received_t_s"],
        **dict(row["meta"]),
    }


def list_images(
    store: Store,
    rover: str,
    t_from: float | None = None,
    t_to: float | None = None,
    kind: str | None = None,
    limit: int = 100,
    offset: int = 0,
) -> tuple[list[dict[str, Any]], int]:
    """A rover's images in time order with their metadata (no pixels), in
    ``[t_from, t_to]`` and of ``kind`` when given: the page ``offset``, ``limit`` and the
    number that match."""
    store._commit_queued()
    t = images_table.c
    where = [t.rover == rover]
    if t_from is not None:
        where.append(t.t_s >= t_from)
    if t_to is not None:
        where.append(t.t_s <= t_to)
    if kind is not None:
        where.append(t.kind == kind)
    with store.engine.connect() as conn:
        counted = select(func.count()).select_from(images_table).where(*where)
        total = int(conn.execute(counted).scalar() or 0)
        query = select(*_LISTED).where(*where).order_by(t.t_s, t.id).limit(limit).offset(offset)
        rows = [_listed(r) for r in conn.execute(query).mappings()]
    return rows, total


def image_detail(store: Store, rover: str, image_id: int) -> dict[str, Any] | None:
    """One image's metadata and features (a VO pair's; ``None`` for a Navcam pair), or
    ``None`` when the rover has no image of that id."""
    store._commit_queued()
    t = images_table.c
    with store.engine.connect() as conn:
        row = conn.execute(
            select(*_LISTED, t.features).where(t.rover == rover, t.id == image_id)
        ).mappings().first()  # fmt: skip
    if row is None:
        return None
    return {**_listed(row), "features": row["features"]}


def image_png(store: Store, rover: str, image_id: int, side: Side) -> bytes | None:
    """The stored PNG of one eye of an image (as stored: never encoded again)."""
    if side not in SIDES:
        raise ValueError(f"side: must be left or right, got {side!r}")
    store._commit_queued()
    t = images_table.c
    column = t.left_png if side == "left" else t.right_png
    with store.engine.connect() as conn:
        data = conn.execute(select(column).where(t.rover == rover, t.id == image_id)).scalar()
    return None if data is None else bytes(data)


@dataclass(frozen=True)
class StereoPair:
    """A stored pair for the ground's terrain map: ``meta`` as ``list_images`` gives it
    (``p_mission_est``, ``q_b_ll_est``, ``mast_az_deg``, ``mast_el_deg``, ``f_px``,
    ``baseline_m``, ...), ``left``/``right`` (H, W) uint8 as the rover sent them."""

    id: int
    t_s: float
    kind: str
    meta: dict[str, Any]
    left: NDArray[np.uint8]
    right: NDArray[np.uint8]


def stereo_pairs(
    store: Store,
    rover: str,
    t_from: float | None = None,
    t_to: float | None = None,
    after_id: int = 0,
    limit: int | None = None,
) -> list[StereoPair]:
    """A rover's pairs (both kinds) with their images decoded, in time order; ``after_id``:
    only those stored after that id (a map that has taken the earlier ones), in the order
    stored when ``limit`` (at most that many) is given."""
    store._commit_queued()
    t = images_table.c
    where = [t.rover == rover, t.id > after_id]
    if t_from is not None:
        where.append(t.t_s >= t_from)
    if t_to is not None:
        where.append(t.t_s <= t_to)
    query = select(*_LISTED, t.left_png, t.right_png).where(*where)
    query = query.order_by(t.t_s, t.id) if limit is None else query.order_by(t.id).limit(limit)
    with store.engine.connect() as conn:
        rows = list(conn.execute(query).mappings())
    return [
        StereoPair(
            int(r["id"]),
            float(r["t_s"]),
            str(r["kind"]),
            _listed(r),
            decode_png(bytes(r["left_png"])),
            decode_png(bytes(r["right_png"])),
        )
        for r in rows
    ]
