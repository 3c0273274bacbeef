"""Images as products the rover sends (``sim.loop.images``, ``sim.comm.store``): their size
on the link (two ICER frames at 2 bits a pixel, and the metadata packed), their priority (the
decimated telemetry's), the 8-bit companding, and the record carrying no truth."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from sim.comm.store import HEADER_BITS, PRIORITY_DECIMATED, OnboardStore, packed_bits
from sim.loop.images import (
    BITS_PER_PIXEL,
    METADATA_FIELDS,
    ImageDict,
    image_bits,
    image_record,
    metadata,
    to_8bit,
)


def _record(width: int, t_s: float = 100.0) -> ImageDict:
    rng = np.random.default_rng(5)
    left = rng.uniform(0.0, 4095.0, (width, width)).astype(np.float32)
    return image_record(
        t_s=t_s, kind="navcam_stereo", left_dn=left, right_dn=left[:, ::-1], f_px=300.0,
        baseline_m=0.2, mast_az_rad=0.1, mast_el_rad=-0.6, site_index=0,
        p_s_est=[1.0, 2.0, 0.0], p_mission_est=[1.0, 2.0, 0.0], q_b_ll_est=[0, 0, 0, 1],
    )  # fmt: skip


@pytest.mark.parametrize("width", [256, 1024])
def test_a_pair_costs_two_compressed_frames_and_its_metadata(width: int) -> None:
    record = _record(width)
    # two frames of width^2 pixels at 2 bits each: 262,144 bits at 256, 4,194,304 at 1024
    assert image_bits(width, width) == 2 * width * width * 2
    assert BITS_PER_PIXEL == 2.0
    store = OnboardStore(capacity_bits=10**9)
    store.add_image(record, image_bits(width, width))
    (product,) = [p for p in [store.next_ready(1e9)] if p is not None]
    assert product.kind == "image" and product.priority == PRIORITY_DECIMATED
    assert product.bits == HEADER_BITS + packed_bits(metadata(record)) + 4 * width * width
    assert product.t_s == 100.0


def test_images_wait_behind_the_reports_and_go_with_the_decimated_telemetry_by_age() -> None:
    store = OnboardStore(capacity_bits=10**9, decimate_s=60.0)
    store.add_frame({"t_s": 50.0, "nate_mode": "Idle", "events": []})  # decimated: priority 1
    store.add_image(_record(256, t_s=60.0), image_bits(256, 256))
    store.add_report(70.0, {"type": "command"})
    order = []
    while (p := store.next_ready(1e9)) is not None:
        order.append(p.kind)
        store.remove(p)
    assert order == ["report", "frame", "image"]


def test_an_overflowing_store_drops_images_into_a_gap_it_reports() -> None:
    bits = image_bits(256, 256)
    store = OnboardStore(capacity_bits=int(2.5 * bits))
    for k in range(4):
        store.add_image(_record(256, t_s=10.0 * k), bits)
    assert store.stats.dropped == 2
    gap = store.next_ready(1e9)
    assert gap is not None and gap.kind == "gap"
    assert gap.payload["kind"] == "image" and gap.payload["count"] == 2


def test_the_twelve_bit_pixels_are_companded_by_a_square_root() -> None:
    dn = np.array([0.0, 4095.0 / 4.0, 4095.0, 5000.0, -3.0])
    assert to_8bit(dn).tolist() == [0, 128, 255, 255, 0]  # 255 * sqrt(1/4) = 127.5 -> 128


def test_the_record_holds_what_the_rover_knows_and_its_images() -> None:
    record = _record(256)
    assert set(record) == {*METADATA_FIELDS, "left", "right"}
    for name in record:
        assert "true" not in name and "depth" not in name
    assert record["left"].dtype == np.uint8 and record["left"].shape == (256, 256)
    assert record["mast_az_deg"] == pytest.approx(np.degrees(0.1))
    with pytest.raises(ValueError, match="kind"):
        image_record(**{**_kwargs(), "kind": "selfie"})


def _kwargs() -> dict[str, Any]:
    z = np.zeros((4, 4), np.float32)
    return dict(t_s=0.0, kind="vo_pair", left_dn=z, right_dn=z, f_px=1.0, baseline_m=0.2,
                mast_az_rad=0.0, mast_el_rad=0.0, site_index=0, p_s_est=[0, 0, 0],
                p_mission_est=[0, 0, 0], q_b_ll_est=[0, 0, 0, 1])  # fmt: skip


def test_an_image_in_the_store_survives_a_checkpoint_pixel_for_pixel() -> None:
    from server.storage.checkpoint import decode, encode

    record = _record(256)
    store = OnboardStore(capacity_bits=10**9)
    store.add_image(record, image_bits(256, 256))
    back = OnboardStore.from_state(decode("spirit", encode("spirit", store.state())))
    product = back.next_ready(1e9)
    assert product is not None and product.kind == "image"
    assert product.bits == store.used_bits == back.used_bits
    for side in ("left", "right"):
        assert product.payload[side].dtype == np.uint8
        assert np.array_equal(product.payload[side], record[side])
    assert product.payload["p_mission_est"] == record["p_mission_est"]
