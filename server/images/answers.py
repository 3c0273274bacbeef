"""What the image routes answer (``server.images.api``): one pydantic model per answer, as
``server.api.answers`` does for the others. The fields are the image record's
(``sim.loop.images.ImageDict``) without its pixels, which are served as PNG."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from server.api.answers import Answer


class VoStep(Answer):
    """A VO pair's step: ``step`` of ``steps`` (0: a drive's first pair), VO's status and
    reason, the counts, and the pose VO measured when it converged (mission frame)."""

    step: int
    steps: int
    status: str = Field(description="estimation.vo.odometry.VoStatus: converged, ...")
    reason: str
    n_features: int = Field(description="features stereo-matched in this pair")
    n_tracked: int = Field(description="the previous pair's features tracked into this one")
    n_inliers: int = Field(description="tracked features RANSAC kept")
    p_mission_vo: list[float] | None = Field(description="position VO measured, m (null: none)")
    q_b_ll_vo: list[float] | None = Field(description="attitude VO measured, [x, y, z, w]")


class Features(Answer):
    """What a VO step saw, pixels ``[u, v]`` of the left image (Cheng, Maimone and Matthies
    2005 Figs. 5-6): the features matched in this pair; the previous pair's features
    tracked into it, where they were and where they are; which of those are inliers."""

    features_uv_px: list[list[float]]
    tracked_previous_uv_px: list[list[float]]
    tracked_uv_px: list[list[float]]
    inlier: list[bool]


class ImageMeta(Answer):
    """An image the rover sent: when, what, the rig, the mast's commanded pointing, where
    the rover believed it was (its estimate, as its downlink reports it), and a VO step's
    outcome; its images at ``.../images/{id}/left.png`` and ``right.png``."""

    id: int
    t_s: float = Field(description="when the pair was taken, TT seconds from J2000")
    kind: Literal["navcam_stereo", "vo_pair"]
    width_px: int
    height_px: int
    received_t_s: float | None = Field(description="on the ground then (null: as it was made)")
    f_px: float = Field(description="the rig's focal length, pixels")
    baseline_m: float = Field(description="the stereo baseline, m")
    mast_az_deg: float = Field(description="the mast's commanded azimuth, deg")
    mast_el_deg: float = Field(description="the mast's commanded elevation, deg")
    site_index: int
    p_s_est: list[float] = Field(description="estimated position in the Site, m")
    p_mission_est: list[float] = Field(description="estimated position, mission frame, m")
    q_b_ll_est: list[float] = Field(description="estimated attitude q_b_ll, [x, y, z, w]")
    vo: VoStep | None = Field(description="a VO pair's step (null: a NAVCAM_STEREO pair)")


class ImageDetail(ImageMeta):
    """One image's metadata and, for a VO pair, what the step saw."""

    features: Features | None


class ImageList(Answer):
    """A page of a rover's images in time order: ``total`` match the filters."""

    images: list[ImageMeta]
    total: int
    limit: int
    offset: int
