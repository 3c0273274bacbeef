"""The February 2005 sanity constraints on a VO update (Cheng, Maimone and Matthies 2005 end of sec.
2; estimation/vo/sanity.py) and the validation of VoParams (estimation/vo/params.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from estimation.vo.params import VoParams
from estimation.vo.sanity import SanityLimits, roll_pitch_yaw, update_of, violation

I3 = np.eye(3)
WHEELS_P = np.array([0.5, 0.0, 0.0])  # wheel odometry: 50 cm straight ahead
ALL_OFF = SanityLimits(
    max_update_m=None, max_update_x_m=None, max_update_y_m=None, max_roll_update_rad=None,
    max_pitch_update_rad=None, max_yaw_update_rad=None, max_downslope_angle_rad=None,
)  # fmt: skip


def _yaw(deg: float) -> np.ndarray:
    out: np.ndarray = Rotation.from_euler("Z", deg, degrees=True).as_matrix()
    return out


def test_roll_pitch_yaw_is_the_z_y_x_convention() -> None:
    R = Rotation.from_euler("ZYX", [120.0, -20.0, 7.0], degrees=True).as_matrix()
    roll, pitch, yaw = roll_pitch_yaw(R)
    assert (math.degrees(roll), math.degrees(pitch), math.degrees(yaw)) == pytest.approx(
        (7.0, -20.0, 120.0)
    )


def test_update_is_expressed_in_the_site_frame() -> None:
    """Rover heading East (yaw +90 deg): a VO position 10 cm short of wheel odometry along
    body x is a 10 cm update towards the West (-y in Site)."""
    update = update_of(I3, [0.4, 0.0, 0.0], I3, WHEELS_P, _yaw(90.0))
    np.testing.assert_allclose(update.dp_s, [0.0, -0.1, 0.0], atol=1e-12)
    assert update.d_yaw_rad == pytest.approx(0.0)
    assert update.tilt_rad == pytest.approx(0.0)
    assert not np.any(update.downslope_s)  # level: no downslope direction
    assert violation(update, SanityLimits()) is None


@pytest.mark.parametrize(
    ("vo_R", "vo_p", "limits", "words"),
    [
        (I3, [1.7, 0.0, 0.0], SanityLimits(), "update magnitude"),
        (I3, [0.5, 0.0, 0.35], dataclasses.replace(ALL_OFF, max_update_m=0.3), "magnitude"),
        (I3, [0.2, 0.0, 0.0], dataclasses.replace(ALL_OFF, max_update_x_m=0.2), "Site X"),
        (I3, [0.5, 0.25, 0.0], dataclasses.replace(ALL_OFF, max_update_y_m=0.2), "Site Y"),
        (Rotation.from_euler("X", 6, degrees=True).as_matrix(), WHEELS_P, SanityLimits(), "roll"),
        (Rotation.from_euler("Y", -6, degrees=True).as_matrix(), WHEELS_P, SanityLimits(),
         "pitch"),
        (_yaw(12.0), WHEELS_P, SanityLimits(), "yaw"),
    ],
)  # fmt: skip
def test_each_kind_of_bad_update_is_refused(
    vo_R: np.ndarray, vo_p: list[float], limits: SanityLimits, words: str
) -> None:
    update = update_of(vo_R, vo_p, I3, WHEELS_P, I3)
    problem = violation(update, limits)
    assert problem is not None and words in problem
    # The same update passes once that constraint is switched off.
    assert violation(update, ALL_OFF) is None


def test_update_not_downslope_is_refused_on_a_slope_only() -> None:
    """Rover pitched 20 deg nose-up on a slope: downslope is backwards along the deck."""
    R_s_b0 = Rotation.from_euler("ZYX", [0.0, 20.0, 0.0], degrees=True).as_matrix()
    limits = dataclasses.replace(ALL_OFF, max_downslope_angle_rad=math.radians(45.0))
    slipped = update_of(I3, [0.3, 0.0, 0.0], I3, WHEELS_P, R_s_b0)  # 20 cm short: downhill
    assert slipped.tilt_rad == pytest.approx(math.radians(20.0))
    assert slipped.downslope_angle_rad == pytest.approx(0.0, abs=1e-9)
    assert violation(slipped, limits) is None
    uphill = update_of(I3, [0.7, 0.0, 0.0], I3, WHEELS_P, R_s_b0)  # 20 cm further: uphill
    assert uphill.downslope_angle_rad == pytest.approx(math.pi)
    problem = violation(uphill, limits)
    assert problem is not None and "downslope" in problem
    sideways = update_of(I3, [0.5, 0.2, 0.0], I3, WHEELS_P, R_s_b0)
    assert sideways.downslope_angle_rad == pytest.approx(math.radians(90.0))
    assert violation(sideways, limits) is not None
    # Level ground, or an update too small to have a direction: not checked.
    assert violation(update_of(I3, [0.7, 0.0, 0.0], I3, WHEELS_P, I3), limits) is None
    assert violation(update_of(I3, [0.51, 0.0, 0.0], I3, WHEELS_P, R_s_b0), limits) is None


def test_sanity_limits_are_validated() -> None:
    with pytest.raises(ValueError, match="max_update_m"):
        SanityLimits(max_update_m=-1.0)
    with pytest.raises(ValueError, match="max_yaw_update_rad"):
        SanityLimits(max_yaw_update_rad=math.nan)
    with pytest.raises(ValueError, match="R_s_b0"):
        update_of(I3, WHEELS_P, I3, WHEELS_P, 2 * I3)
    with pytest.raises(ValueError, match="p_b1_b0_vo"):
        update_of(I3, [0.0, 0.0], I3, WHEELS_P, I3)


@pytest.mark.parametrize(
    ("changes", "name"),
    [
        ({"n_features": 0}, "n_features"),
        ({"n_features": 2.5}, "n_features"),
        ({"window_px": 8}, "window_px"),
        ({"grid_cell_px": 40}, "grid_cell_px"),
        ({"min_score": 1.5}, "min_score"),
        ({"max_gap_m": -0.01}, "max_gap_m"),
        ({"min_disparity_px": 300.0}, "min_disparity_px"),
        ({"min_inliers": 4}, "min_inliers"),
        ({"min_features": 5}, "min_features"),
        ({"harris_aperture_px": 4}, "harris_aperture_px"),
        ({"track_max_error_m": math.inf}, "track_max_error_m"),
        ({"sanity": None}, "sanity"),
    ],
)
def test_vo_params_name_the_bad_parameter(changes: dict[str, object], name: str) -> None:
    with pytest.raises(ValueError, match=name):
        VoParams(**changes)  # type: ignore[arg-type]


def test_params_for_width_scale_pixels_not_metres() -> None:
    full = VoParams()
    small = full.for_width(256)
    assert small.window_px % 2 == 1 and 7 <= small.window_px < full.window_px
    assert small.max_disparity_px == pytest.approx(full.max_disparity_px / 4)
    assert small.ransac_threshold_px == pytest.approx(full.ransac_threshold_px / 4)
    assert small.grid_cell_px < small.min_separation_px
    assert small.max_gap_m == full.max_gap_m and small.n_features == full.n_features
    assert full.for_width(1024) == full
    with pytest.raises(ValueError, match="width_px"):
        full.for_width(10)
