"""An image the rover sends down: a Navcam stereo pair and its record, one definition.

What the rover knows and nothing else (docs/DESIGN.md, "Two records"): the time it took the
pair, its kind (``navcam_stereo``, a NAVCAM_STEREO command's; ``vo_pair``, a pair a ``vo=on
vo_keep_images=on`` drive kept), the rig's size and focal length, the mast's *commanded*
pointing, the rover's *estimated* pose when the pair was taken as its downlink reports it
(Site and mission positions, ``q_b_ll``: what the ground places the pair's stereo with), and
for a VO pair the step's outcome and what it saw (``estimation.vo.odometry.VoFeatures``:
features, tracked pixels before and after, inliers; Cheng, Maimone and Matthies 2005 Figs.
5-6 draw these). The renderer's true pose, its depth maps and the true mast pointing stay in
the simulator.

The images are 8 bits a pixel: the Navcams' 12-bit DN companded by a square root, as MER's
cameras' 12-to-8-bit lookup tables did (Maki et al. 2003). On the link a pair costs what two
compressed frames do: ICER (Kiely and Klimesh 2003), MER's wavelet compressor, at
``BITS_PER_PIXEL`` = 2 bits a pixel (the rate is this project's choice within ICER's lossy
range, between about 1 bit a pixel and the lossless 4-5), plus a packet of metadata
(``sim.comm.store.packed_bits``). A 256 x 256 pair is 262,144 bits of image, a 1024 x 1024
pair 4,194,304.
"""

from __future__ import annotations

import math
from typing import Any, Literal, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray
from typing_extensions import TypedDict

from estimation.vo.odometry import VoFeatures, VoResult

ImageKind = Literal["navcam_stereo", "vo_pair"]
IMAGE_KINDS: tuple[ImageKind, ...] = ("navcam_stereo", "vo_pair")
BITS_PER_PIXEL = 2.0  # ICER's compressed rate (module docstring)
DN_MAX = 4095.0  # the Navcams' 12-bit scale (sim.sensors.navcam.camera)
Uint8Image = NDArray[np.uint8]


class VoStepDict(TypedDict):
    """A VO pair's step: ``step`` of ``steps`` (0: the drive's first pair, nothing to
    compare with), VO's ``status`` and ``reason``, the counts, and the pose VO measured
    (``p_mission_vo``, ``q_b_ll_vo``; null unless it converged: SAPP adopted it)."""

    step: int
    steps: int
    status: str
    reason: str
    n_features: int
    n_tracked: int
    n_inliers: int
    p_mission_vo: list[float] | None
    q_b_ll_vo: list[float] | None


class FeaturesDict(TypedDict):
    """``VoFeatures`` as lists of pixels ``[u, v]`` of the left image."""

    features_uv_px: list[list[float]]
    tracked_previous_uv_px: list[list[float]]
    tracked_uv_px: list[list[float]]
    inlier: list[bool]


class ImageDict(TypedDict):
    """One image product (module docstring); ``left``/``right`` (H, W) uint8, rows ``v``."""

    t_s: float
    kind: ImageKind
    width_px: int
    height_px: int
    f_px: float
    baseline_m: float
    mast_az_deg: float
    mast_el_deg: float
    site_index: int
    p_s_est: list[float]
    p_mission_est: list[float]
    q_b_ll_est: list[float]
    vo: VoStepDict | None
    features: FeaturesDict | None
    left: Uint8Image
    right: Uint8Image


METADATA_FIELDS = tuple(k for k in ImageDict.__annotations__ if k not in ("left", "right"))


def to_8bit(dn: NDArray[Any]) -> Uint8Image:
    """12-bit DN (any float array) companded to 8 bits by a square root: ``255
    sqrt(DN / 4095)``, rounded, clipped (Maki et al. 2003's lookup tables)."""
    x = np.clip(np.asarray(dn, dtype=np.float64), 0.0, DN_MAX) / DN_MAX
    return np.rint(255.0 * np.sqrt(x)).astype(np.uint8)


def image_bits(width_px: int, height_px: int) -> int:
    """The two compressed frames of a pair, bits (``BITS_PER_PIXEL``)."""
    return 2 * math.ceil(width_px * height_px * BITS_PER_PIXEL)


def _vec(values: Any) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=float).ravel()]


def _px(values: NDArray[Any]) -> list[list[float]]:
    return [[float(u), float(v)] for u, v in np.asarray(values, dtype=float).reshape(-1, 2)]


def features_dict(features: VoFeatures) -> FeaturesDict:
    """``features`` as plain lists."""
    return {
        "features_uv_px": _px(features.features_uv_px),
        "tracked_previous_uv_px": _px(features.tracked_previous_uv_px),
        "tracked_uv_px": _px(features.tracked_uv_px),
        "inlier": [bool(b) for b in np.asarray(features.inlier).ravel()],
    }


def vo_step_dict(
    result: VoResult,
    step: int,
    steps: int,
    vo_pose: tuple[ArrayLike, ArrayLike] | None,
) -> VoStepDict:
    """A VO step's outcome; ``vo_pose`` the ``(p_mission, q_b_ll)`` it measured (converged)."""
    return {
        "step": int(step),
        "steps": int(steps),
        "status": str(result.status.value),
        "reason": str(result.reason),
        "n_features": int(result.n_features),
        "n_tracked": int(result.n_tracked),
        "n_inliers": int(result.n_inliers),
        "p_mission_vo": None if vo_pose is None else _vec(vo_pose[0]),
        "q_b_ll_vo": None if vo_pose is None else _vec(vo_pose[1]),
    }


def image_record(
    *,
    t_s: float,
    kind: ImageKind,
    left_dn: NDArray[Any],
    right_dn: NDArray[Any],
    f_px: float,
    baseline_m: float,
    mast_az_rad: float,
    mast_el_rad: float,
    site_index: int,
    p_s_est: ArrayLike,
    p_mission_est: ArrayLike,
    q_b_ll_est: ArrayLike,
    vo: VoStepDict | None = None,
    features: FeaturesDict | None = None,
) -> ImageDict:
    """The record of a pair the rover sends (module docstring): the images companded to 8
    bits, angles in degrees at this edge."""
    if kind not in IMAGE_KINDS:
        raise ValueError(f"kind: must be one of {', '.join(IMAGE_KINDS)}, got {kind!r}")
    left, right = to_8bit(left_dn), to_8bit(right_dn)
    if left.ndim != 2 or left.shape != right.shape:
        raise ValueError(f"a pair's images must be 2-D of one shape: {left.shape}, {right.shape}")
    return {
        "t_s": float(t_s),
        "kind": kind,
        "width_px": int(left.shape[1]),
        "height_px": int(left.shape[0]),
        "f_px": float(f_px),
        "baseline_m": float(baseline_m),
        "mast_az_deg": round(math.degrees(mast_az_rad), 9),  # no -119.99999999999999
        "mast_el_deg": round(math.degrees(mast_el_rad), 9),
        "site_index": int(site_index),
        "p_s_est": _vec(p_s_est),
        "p_mission_est": _vec(p_mission_est),
        "q_b_ll_est": _vec(q_b_ll_est),
        "vo": vo,
        "features": features,
        "left": left,
        "right": right,
    }


def metadata(record: ImageDict) -> dict[str, Any]:
    """The record without its images (what is packed beside the compressed frames)."""
    return {k: record[k] for k in METADATA_FIELDS}  # type: ignore[literal-required]


def as_image(payload: dict[str, Any]) -> ImageDict:
    """A product's payload back as the record it was made from (checked: two images)."""
    for side in ("left", "right"):
        if not isinstance(payload.get(side), np.ndarray):
            raise ValueError(f"an image product carries its {side} image as an array")
    return cast(ImageDict, payload)
