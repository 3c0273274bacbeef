"""Every tuning threshold of the MER visual odometry (Cheng, Maimone and Matthies
2005, sec. 2), in one validated dataclass.

Pixel quantities are at the image's own resolution. The defaults suit the full 1024 x 1024
Navcam; :meth:`VoParams.for_width` rescales them for another width (MER ran VO on 256 x 256
images, Cheng, Maimone and Matthies 2005 sec. 4). The paper gives few numbers: 6-point RANSAC
samples, "e.g." a 0.5 px reprojection threshold (at 256 px; we use 0.75 px, see
``ransac_threshold_px``), a 3x3 subpixel fit, "a few pixels" of epipolar slack; the rest were tuned
on rendered Navcam pairs (tests/estimation/vo/test_vo_end_to_end.py, ``roverops bench vo``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from estimation.vo.sanity import SanityLimits

_REFERENCE_WIDTH_PX = 1024


@dataclass(frozen=True)
class VoParams:
    """Visual-odometry thresholds (defaults for 1024 px wide images).

    Features (sec. 2 "Feature Detection"): ``n_features`` kept per pair, strongest first, at
    least ``min_separation_px`` apart, from a grid of ``grid_cell_px`` cells (smaller than
    the separation); Harris ``harris_block_px``, ``harris_aperture_px``, ``harris_k``. They
    are detected on pyramid level ``feature_level`` (0: full resolution) and these four are
    in that level's pixels: at 1024 px the fine pebbles of the near field outscore the
    smoother far field, and full-resolution detection put every feature in the lower half of
    the image, where a 0.75 m step takes it out of view; detected at about 256 px wide, as
    MER's, they span the image (sec. 4.3 tells why that matters: sols 137/141).

    Correlation: ``window_px`` odd template size; ``min_score`` the least pseudo-normalised
    correlation accepted in stereo, ``track_min_score`` between pairs (the viewpoint moved:
    windows foreshorten and rescale, so the scores are lower); a match's covariance is
    ``peak_cov_scale (-H)⁻¹ + min_sigma_px² I`` from its peak curvature ``H``.

    Stereo: ``row_slack_px`` rows above and below the epipolar line; disparities in
    ``[min_disparity_px, max_disparity_px]``; rays missing by more than ``max_gap_m`` or
    points beyond ``max_range_m`` are dropped.

    Tracking: search ``± track_search_radius_px`` around the wheel-odometry prediction, on
    pyramids deep enough to bring that to ``track_coarse_radius_px`` (at most
    ``track_max_levels`` halvings), refining ``± track_refine_radius_px`` per level, with
    templates of ``track_window_px`` at full resolution (the same patch of ground at every
    level). Up to ``track_passes`` passes (``estimation.vo.odometry``): a pass whose RANSAC
    kept at least ``track_guide_min_inliers`` guides the next, which searches only
    ``± track_near_radius_px`` at full resolution around the prediction by that estimate,
    with ``ransac_guided_iterations`` samples beside the guide; passes stop when one gains
    under ``track_pass_min_gain`` (a fraction) more inliers. Features
    whose new 3D point is farther from the prediction than ``track_max_error_m +
    track_max_rotation_error_rad * distance`` are dropped (must exceed the worst slip error
    of a step, in position and in heading).

    Motion: RANSAC with ``ransac_iterations`` samples of ``ransac_sample_size`` features,
    inliers within ``ransac_threshold_px`` (reprojection, both eyes); at least
    ``min_features`` tracked and ``min_inliers`` inliers, else "no update"; Gauss-Newton ML
    refinement for at most ``ml_max_iterations`` steps, converged when a step is under
    ``ml_tol_rad`` and ``ml_tol_m``; an update whose ML covariance has a standard deviation
    over ``max_sigma_m`` (position) or ``max_sigma_rad`` (rotation) on its worst axis is no
    update. ``sanity``: the Feb 2005 constraints.
    """

    n_features: int = 200
    feature_level: int = 2
    grid_cell_px: int = 4
    min_separation_px: float = 10.0
    harris_block_px: int = 2
    harris_aperture_px: int = 3
    harris_k: float = 0.04
    window_px: int = 13
    track_window_px: int = 29
    min_score: float = 0.7
    track_min_score: float = 0.5
    peak_cov_scale: float = 0.003
    min_sigma_px: float = 0.05
    row_slack_px: int = 2
    min_disparity_px: float = 2.0
    max_disparity_px: float = 220.0
    max_gap_m: float = 0.02
    max_range_m: float = 30.0
    track_search_radius_px: float = 256.0
    track_coarse_radius_px: float = 32.0
    track_max_levels: int = 3
    track_refine_radius_px: int = 2
    # Three passes, the later ones ± 3 px at 256: Gusev convergence 90.75 -> 98.0 % and
    # Meridiani 38 -> 98 % (bench vo; one pass is MER's tracking; a third pass added
    # 0.25 % on Gusev); a guide needs only a 6-point sample's worth of inliers, since the
    # near pass and MER's counts judge the result (8: Meridiani 90.6 % on the bench's pairs)
    track_passes: int = 3
    track_near_radius_px: float = 12.0
    track_guide_min_inliers: int = 6
    track_pass_min_gain: float = 0.1
    track_max_error_m: float = 0.6
    track_max_rotation_error_rad: float = math.radians(6.0)
    ransac_iterations: int = 200
    ransac_guided_iterations: int = 50
    ransac_sample_size: int = 6
    # 0.75 px at MER's 256 px (the paper's example is 0.5): on our rendered pairs 0.5 px
    # refused good steps (45 % of Gusev's 0.75 m steps fell under 12 inliers) and 1 px let
    # one step 5.2 cm off through; 0.75 px had none (docs/BENCHMARKS.md, bench vo)
    ransac_threshold_px: float = 3.0
    min_features: int = 20
    min_inliers: int = 12
    ml_max_iterations: int = 20
    ml_tol_rad: float = 1e-7
    ml_tol_m: float = 1e-6
    # An update is kept only if its ML covariance puts its 3σ inside the 5 cm of a false
    # update (docs/BENCHMARKS.md) and its 2σ inside the 1 deg: the false updates that the
    # tracking passes still let through (a wrong first pass, few features) had σ of
    # 2.3-2.9 cm where good steps had at most 1.8 cm (bench vo, 2026-12-05)
    max_sigma_m: float = 0.05 / 3.0
    max_sigma_rad: float = math.radians(0.5)
    sanity: SanityLimits = field(default_factory=SanityLimits)

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "sanity":
                if not isinstance(value, SanityLimits):
                    raise ValueError(f"sanity: must be a SanityLimits, got {value!r}")
                continue
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"{f.name}: must be a number, got {value!r}")
            if f.type == "int" and not isinstance(value, int):
                raise ValueError(f"{f.name}: must be an integer, got {value!r}")
            if f.name == "feature_level" and value == 0:
                continue  # detection at full resolution
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{f.name}: must be positive and finite, got {value!r}")
        self._check_relations()

    def _check_relations(self) -> None:
        if self.grid_cell_px >= self.min_separation_px:
            raise ValueError("grid_cell_px: must be smaller than min_separation_px (sec. 2)")
        if self.window_px < 3 or self.window_px % 2 != 1:
            raise ValueError(f"window_px: must be odd and at least 3, got {self.window_px}")
        if self.harris_aperture_px not in (3, 5, 7):
            raise ValueError(
                f"harris_aperture_px: must be 3, 5 or 7, got {self.harris_aperture_px}"
            )
        if self.harris_block_px < 2:
            raise ValueError(f"harris_block_px: must be at least 2, got {self.harris_block_px}")
        if not 0.0 < self.harris_k < 0.25:
            raise ValueError(f"harris_k: must be in (0, 0.25), got {self.harris_k}")
        if not 0.0 < self.min_score <= 1.0:
            raise ValueError(f"min_score: must be in (0, 1], got {self.min_score}")
        if not 0.0 < self.track_min_score <= 1.0:
            raise ValueError(f"track_min_score: must be in (0, 1], got {self.track_min_score}")
        if self.min_disparity_px >= self.max_disparity_px:
            raise ValueError("min_disparity_px: must be below max_disparity_px")
        if self.ransac_sample_size < 3:
            raise ValueError(
                f"ransac_sample_size: must be at least 3, got {self.ransac_sample_size}"
            )
        if self.min_inliers < self.ransac_sample_size:
            raise ValueError("min_inliers: must be at least ransac_sample_size")
        if not self.ransac_sample_size <= self.track_guide_min_inliers <= self.min_inliers:
            raise ValueError(
                "track_guide_min_inliers: must be in [ransac_sample_size, min_inliers]"
            )
        if self.min_features < self.min_inliers:
            raise ValueError("min_features: must be at least min_inliers")

    def for_width(self, width_px: int) -> VoParams:
        """These parameters for images ``width_px`` wide (same field of view): pixel
        distances scale with the width; the correlation window and the coarsest tracking
        radius shrink as its square root (a window must stay distinctive, and the coarse
        pyramid level must keep enough pixels), the window never below 7 px; the peak
        covariance scale grows as the window's area shrinks; counts and metric limits
        stay."""
        if width_px < 64:
            raise ValueError(f"width_px: must be at least 64, got {width_px}")
        s = width_px / _REFERENCE_WIDTH_PX
        window = max(7, 2 * round(0.5 * (self.window_px * math.sqrt(s) - 1)) + 1)
        track_window = max(7, 2 * round(0.5 * (self.track_window_px * s - 1)) + 1)
        # detection keeps an image about as wide as the reference's detection level
        level = max(0, self.feature_level + round(math.log2(s)))
        s_level = (width_px / 2**level) / (_REFERENCE_WIDTH_PX / 2**self.feature_level)
        cell = max(2, round(self.grid_cell_px * s_level))
        return dataclasses.replace(
            self,
            feature_level=level,
            grid_cell_px=cell,
            min_separation_px=max(self.min_separation_px * s_level, cell + 1.0),
            harris_block_px=max(2, round(self.harris_block_px * math.sqrt(s_level))),
            window_px=window,
            track_window_px=track_window,
            # The score's noise variance falls as the window's pixel count grows.
            peak_cov_scale=self.peak_cov_scale * (self.window_px / window) ** 2,
            min_sigma_px=self.min_sigma_px * s,
            min_disparity_px=self.min_disparity_px * s,
            max_disparity_px=self.max_disparity_px * s,
            track_search_radius_px=self.track_search_radius_px * s,
            track_coarse_radius_px=max(4.0, self.track_coarse_radius_px * math.sqrt(s)),
            track_near_radius_px=max(2.0, self.track_near_radius_px * s),
            ransac_threshold_px=self.ransac_threshold_px * s,
        )
