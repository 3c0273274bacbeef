"""Single-precision standard normal draws, bit-identical to numpy's, a few times faster.

The Pancam read noise is one float32 standard normal per pixel, a million per frame, and
``Generator.standard_normal(dtype=np.float32)`` takes ~9 ms a frame on the reference machine,
fetching its random words from the bit generator one call at a time.
:func:`standard_normal_f32` draws the same words in bulk (``PCG64.random_raw``) and runs the
same algorithm on them in a numba loop (~3 ms), so that a frame's noise, and every draw
after it, stays exactly what numpy would have produced.

The algorithm is numpy's single-precision ziggurat: Marsaglia and Tsang 2000 (J. Stat.
Softw. 5(8), "The Ziggurat Method for Generating Random Variables") with 256 layers of
area ``v`` over a base of tail ``r``. Each draw takes a 32-bit word ``w``: ``w & 0xff`` is
the layer ``i``, bit 8 the sign, the top 23 bits ``j``; ``x = j wi[i]`` is returned when
``j < ki[i]`` (inside the layer's rectangle, ~99 % of draws); otherwise layer 0 samples the
tail beyond ``r`` (Marsaglia and Tsang's exponential method), and the other layers
accept ``x`` if a uniform height in the wedge lies under ``exp(-x^2 / 2)``, else draw again.
Uniforms are ``(word >> 8) / 2^24``.

The tables are the paper's construction: ``x_255 = r``, ``x_(i-1) = sqrt(-2 ln(v / x_i +
f(x_i)))``, ``f(x) = exp(-x^2 / 2)``; the base strip's width ``x_0 = v / f(r)``;
``wi = x / 2^23``, ``fi = f(x)`` in float32, ``ki[i] = round(2^23 x_(i-1) / x_i)``
(``ki[0]`` with ``r`` for ``x_(-1)``, ``ki[1] = 0``: the top layer is all wedge). The test
checks the draws against numpy's, bit for bit, over every branch.

The word stream is PCG64's ``next_uint32``: the low then the high half of each 64-bit
output, the high half kept (``has_uint32``) for the next call. Other bit generators, other
dtypes or a big-endian machine take numpy's own path.
"""

from __future__ import annotations

import math
import sys
from typing import Any, cast

import numba
import numpy as np
from numpy.typing import NDArray

# Marsaglia and Tsang 2000: the 256-layer normal ziggurat's tail start and layer area.
ZIGGURAT_R = 3.6541528853610088
ZIGGURAT_V = 0.00492867323399
_R_F32 = np.float32(ZIGGURAT_R)
_INV_R_F32 = np.float32(1.0 / ZIGGURAT_R)
_UNIFORM_SCALE_F32 = np.float32(1.0 / 16_777_216.0)  # 2^-24: a word's top 24 bits in [0, 1)


def _tables() -> tuple[NDArray[np.float32], NDArray[np.uint32], NDArray[np.float32]]:
    """``wi``, ``ki``, ``fi`` (256,) of the float32 ziggurat (module docstring)."""

    def f(x: float) -> float:
        return math.exp(-0.5 * x * x)

    x = [0.0] * 256
    x[255] = ZIGGURAT_R
    for i in range(255, 1, -1):
        x[i - 1] = math.sqrt(-2.0 * math.log(ZIGGURAT_V / x[i] + f(x[i])))
    x[0] = ZIGGURAT_V / f(ZIGGURAT_R)
    wi = np.array([xi / 2.0**23 for xi in x], dtype=np.float32)
    ki = np.zeros(256, dtype=np.uint32)
    ki[0] = round(2.0**23 * ZIGGURAT_R / x[0])
    for i in range(2, 256):
        ki[i] = round(2.0**23 * x[i - 1] / x[i])
    fi = np.array([1.0] + [f(xi) for xi in x[1:]], dtype=np.float32)
    return wi, ki, fi


WI_F32, KI_U32, FI_F32 = _tables()


# 64-bit words drawn per call of the generator: 128 KB, which stays in cache between the
# generator's writing it and the kernel's reading it (and is reused from the heap instead of
# faulting in a fresh 4 MB each frame); larger chunks measured slower, smaller no faster.
_CHUNK_RAW = 1 << 14


@numba.njit(cache=True, nogil=True)
def _draw_slow(
    words: Any, w: int, word: Any, wi: Any, fi: Any, r: Any, inv_r: Any, scale: Any
) -> tuple[Any, int, int]:  # pragma: no cover - compiled; the test compares it with numpy
    """The rare rest of a draw whose ``word`` fell outside its layer's rectangle: the tail
    beyond r (layer 0) or the wedge test, from ``words[w:]``. Returns the value, the next
    word's index and 1 if accepted, 0 if the draw starts over there, -1 if the words end."""
    n_words = words.size
    idx = word & 0xFF
    j = (word >> 9) & 0x7FFFFF
    x = np.float32(j) * wi[idx]
    if (word >> 8) & 1:
        x = -x
    if idx == 0:
        while w + 1 < n_words:
            u1 = np.float32(words[w] >> 8) * scale
            u2 = np.float32(words[w + 1] >> 8) * scale
            w += 2
            xx = -inv_r * np.float32(math.log1p(-u1))
            yy = -np.float32(math.log1p(-u2))
            if yy + yy > xx * xx:
                return (-(r + xx) if (j >> 8) & 1 else r + xx), w, 1
        return x, w, -1
    if w >= n_words:
        return x, w, -1
    u = np.float32(words[w] >> 8) * scale
    xd = np.float64(x)
    accepted = (fi[idx - 1] - fi[idx]) * u + fi[idx] < math.exp(-0.5 * xd * xd)
    return x, w + 1, 1 if accepted else 0


@numba.njit(cache=True, nogil=True)
def _fill(
    words: Any,
    out: Any,
    start: int,
    gain: Any,
    offset: Any,
    affine: bool,
    wi: Any,
    ki: Any,
    fi: Any,
    r: Any,
    inv_r: Any,
    scale: Any,
) -> tuple[int, int]:  # pragma: no cover - compiled; the test compares it with numpy
    """Fill ``out[start:]`` from the word stream ``words`` (each draw ``z``, or ``z * gain +
    offset`` in float32 if ``affine``); returns the next index of ``out`` and the words used.
    Stops before a draw the words cannot finish."""
    i = start
    w = first = 0  # first: where the current draw began, rewound to if the words run out
    while i < out.size and w < words.size:
        word = words[w]
        idx = word & 0xFF
        j = (word >> 9) & 0x7FFFFF
        if j < ki[idx]:  # ~99 % of draws: inside the layer's rectangle
            x = np.float32(j) * wi[idx]
            w += 1
            if (word >> 8) & 1:
                x = -x
        else:
            x, w, status = _draw_slow(words, w + 1, word, wi, fi, r, inv_r, scale)
            if status < 0:
                break
            if status == 0:
                continue
        # float32 products and sums, each rounded, as numpy's in-place *= and +=
        out[i] = x * gain + offset if affine else x
        i += 1
        first = w
    return i, first


def standard_normal_f32(
    rng: np.random.Generator,
    out: NDArray[np.float32],
    gain: np.float32 | None = None,
    offset: np.float32 | None = None,
) -> None:
    """``rng.standard_normal(dtype=np.float32, out=out)``, the same values and the same
    generator state afterwards; ``out`` C-contiguous float32. With ``gain`` and ``offset``,
    then ``out *= gain; out += offset``, done in the same pass."""
    affine = gain is not None and offset is not None
    if not (_bulk(rng) and out.dtype == np.float32 and out.flags.c_contiguous):
        rng.standard_normal(dtype=np.float32, out=out)
        if gain is not None and offset is not None:
            out *= gain
            out += offset
        return
    g = np.float32(1.0) if gain is None else np.float32(gain)
    o = np.float32(0.0) if offset is None else np.float32(offset)
    _stream(rng, out.reshape(-1), g, o, affine)


def _bulk(rng: np.random.Generator) -> bool:
    """Whether ``rng``'s words can be drawn in bulk here (PCG64, little-endian)."""
    return type(rng.bit_generator) is np.random.PCG64 and sys.byteorder == "little"


def _stream(
    rng: np.random.Generator,
    flat: NDArray[np.float32],
    gain: np.float32,
    offset: np.float32,
    affine: bool,
) -> None:
    """Fill ``flat`` (``_fill``) chunk by chunk of the generator's 32-bit words, leaving the
    generator as numpy's draws would."""
    n = flat.size
    bits = rng.bit_generator
    state = cast(dict[str, Any], bits.state)
    # Words in hand: the half word the generator kept, then what a stalled draw left.
    head = np.array([state["uinteger"]] if state["has_uint32"] else [], dtype=np.uint32)
    high = int(state["uinteger"])  # the last high half drawn: numpy keeps it even when used
    done = 0
    least = 0  # words to add at the least: 1 once the words in hand could not finish a draw
    while done < n:
        # One word at least per draw: never more words than draws left (plus the odd half
        # word that the generator then keeps for its next call, as numpy's does).
        short = max(n - done - head.size, least)
        least = 1
        words = head
        if short > 0:
            raw = bits.random_raw(min((short + 1) // 2, _CHUNK_RAW)).view(np.uint32)
            high = int(raw[-1])  # low, high halves: the last word is a high half
            words = np.concatenate([head, raw]) if head.size else raw
        done, used = _fill(
            words, flat, done, gain, offset, affine,
            WI_F32, KI_U32, FI_F32, _R_F32, _INV_R_F32, _UNIFORM_SCALE_F32,
        )  # fmt: skip
        head = words[used:]
    state = cast(dict[str, Any], bits.state)
    state["has_uint32"] = int(head.size)
    state["uinteger"] = high
    bits.state = state
