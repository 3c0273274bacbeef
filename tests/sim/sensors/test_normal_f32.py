"""The bulk float32 normal draws against numpy's own ``Generator.standard_normal``: the same
values bit for bit, the same generator state afterwards, over every branch."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.sensors.normal_f32 import FI_F32, KI_U32, WI_F32, ZIGGURAT_R, standard_normal_f32


def _pair(seed: int, skip: int) -> tuple[np.random.Generator, np.random.Generator]:
    """Two generators in one state; ``skip`` float32 draws first, so that an odd number of
    32-bit words leaves half a word kept (``has_uint32``)."""
    a, b = np.random.default_rng(seed), np.random.default_rng(seed)
    a.standard_normal(skip, dtype=np.float32)
    b.standard_normal(skip, dtype=np.float32)
    return a, b


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("shape", [(1,), (2,), (7,), (3, 5), (1024, 1024)])
def test_the_draws_are_numpys_bit_for_bit(seed: int, shape: tuple[int, ...]) -> None:
    ref, fast = _pair(seed, skip=seed)
    for _ in range(3):
        expected = ref.standard_normal(shape, dtype=np.float32)
        got = np.empty(shape, dtype=np.float32)
        standard_normal_f32(fast, got)
        np.testing.assert_array_equal(got.view(np.uint32), expected.view(np.uint32))
        assert fast.bit_generator.state == ref.bit_generator.state
    # whatever is drawn next agrees too: the stream is where numpy leaves it
    assert fast.random() == ref.random()
    assert fast.standard_normal(dtype=np.float32) == ref.standard_normal(dtype=np.float32)


def test_every_branch_is_taken_and_agrees() -> None:
    """4 million draws: the tail beyond r (~1,000 of them) and the wedges (~1 %)."""
    ref, fast = _pair(7, skip=1)
    expected = ref.standard_normal(4 * 1024 * 1024, dtype=np.float32)
    got = np.empty_like(expected)
    standard_normal_f32(fast, got)
    np.testing.assert_array_equal(got.view(np.uint32), expected.view(np.uint32))
    assert np.count_nonzero(np.abs(expected) > ZIGGURAT_R) > 500  # the tail
    # the wedges: words whose layer i > 0 rejects j at once (j >= ki[i]) are in the stream
    words = np.random.default_rng(7).bit_generator.random_raw(2 * 1024 * 1024).view(np.uint32)
    layer, j = words & 0xFF, words >> 9
    assert np.count_nonzero((layer > 0) & (j >= KI_U32[layer])) > 10_000
    assert abs(float(expected.mean())) < 5.0 / math.sqrt(expected.size)
    assert abs(float(expected.std()) - 1.0) < 1e-3


def test_the_tables_follow_marsaglia_and_tsang() -> None:
    assert WI_F32[255] * np.float32(2.0**23) == np.float32(ZIGGURAT_R)  # x_255 = r
    assert KI_U32[1] == 0  # the top layer is all wedge
    assert FI_F32[0] == 1.0 and np.all(np.diff(FI_F32) < 0.0)
    assert np.all(np.diff(WI_F32[1:]) > 0.0)


def test_other_bit_generators_take_numpys_path() -> None:
    ref = np.random.Generator(np.random.MT19937(5))
    fast = np.random.Generator(np.random.MT19937(5))
    expected = ref.standard_normal((4, 6), dtype=np.float32)
    got = np.empty((4, 6), dtype=np.float32)
    standard_normal_f32(fast, got)
    np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("seed", [0, 5])
def test_the_scaled_draws_are_numpys_scaled_in_place(seed: int) -> None:
    """With a gain and an offset: numpy's draws, then ``*= gain`` and ``+= offset``."""
    ref, fast = _pair(seed, skip=seed)
    gain, offset = np.float32(1.25), np.float32(100.0)
    for shape in [(1024, 1024), (3, 7)]:
        expected = ref.standard_normal(shape, dtype=np.float32)
        expected *= gain
        expected += offset
        got = np.empty(shape, dtype=np.float32)
        standard_normal_f32(fast, got, gain, offset)
        np.testing.assert_array_equal(got.view(np.uint32), expected.view(np.uint32))
    assert fast.bit_generator.state == ref.bit_generator.state
    mt_ref, mt_fast = (
        np.random.Generator(np.random.MT19937(1)),
        np.random.Generator(np.random.MT19937(1)),
    )
    expected = mt_ref.standard_normal(9, dtype=np.float32) * gain + offset
    got = np.empty(9, dtype=np.float32)
    standard_normal_f32(mt_fast, got, gain, offset)
    np.testing.assert_array_equal(got, expected)
