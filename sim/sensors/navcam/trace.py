"""Ray casting over a local height grid: the numba kernels of the Navcam renderer.

The terrain in view is sampled onto a regular grid (``HeightGrid``): elevations ``H[i, j]``
at ``x = i s``, ``y = j s`` in a local frame (x North, y East, z *up*, metres from the
grid's corner), the surface between samples being their bilinear interpolant -- exactly
the surface of ``sim.world.heightmap`` when the grid sits on the heightmap's lattice.

Each pixel's ray is cast through a *maximum mipmap* (Tevs, Ihrke and Seidel 2008,
"Maximum mipmaps for fast, accurate, and scalable dynamic height field rendering", I3D):
level 0 holds each cell's highest corner (a bilinear patch never rises above its
corners), level ``L`` the maximum over ``2^L x 2^L`` cells. A ray skips a whole cell of
level ``L`` when it passes above that cell's maximum; otherwise it descends, and in a
level-0 cell the crossing with the bilinear patch is solved exactly: along the ray the
patch height is a quadratic in the ray parameter, so the first crossing is the first root
of a quadratic -- no fixed step, no bisection, no missed thin rocks.

Shading normals are the bilinear interpolation of per-sample gradients (central
differences), the Gouraud-style smoothing that hides the 5 cm facets of the grid at close
range; the geometry (hits, depths, shadows) uses the exact bilinear surface.

A shadow ray from each lit ground point towards the Sun uses the same caster; the rover's
own shadow tests that ray against boxes and finite cylinders in the body frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar, cast

import numba
import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_F = TypeVar("_F", bound=Callable[..., Any])

# Step past a cell boundary after leaving a cell: 1 nm, far below any feature and far above
# float64 rounding of positions within a few hundred metres (~1e-13 m).
_NUDGE_M = 1e-9
# Shadow rays start above the lit point (vertically): 0.1 mm against rounding, plus the
# height the grid's facets can rise above the smooth shading surface within a cell
# (``_terminator_lift_m``), at most half a cell.
SHADOW_LIFT_M = 1e-4
TERMINATOR_LIFT_MAX_CELLS = 0.5


def kernel(fn: _F) -> _F:
    """Compile ``fn`` with numba: nopython, cached on disk, without the GIL."""
    return cast(_F, numba.njit(cache=True, nogil=True)(fn))


def parallel_kernel(fn: _F) -> _F:
    """As ``kernel``, with ``numba.prange`` loops spread over the CPU's threads."""
    return cast(_F, numba.njit(cache=True, nogil=True, parallel=True)(fn))


@dataclass(frozen=True)
class HeightGrid:
    """Elevations on a regular grid and what the caster needs to traverse it.

    ``heights`` (ni, nj): elevation up (m) at local ``(i s, j s)``; the local frame's corner
    is at Site ``(x0_m, y0_m)``. ``grad_x``, ``grad_y`` (ni, nj): per-sample slopes for the
    shading normals. ``max_pyramid``: all mipmap levels flattened, level ``L`` at
    ``level_offset[L]`` with shape ``(level_ni[L], level_nj[L])``; the last level is 1 x 1.
    """

    heights: FloatArray
    x0_m: float
    y0_m: float
    spacing_m: float
    grad_x: FloatArray
    grad_y: FloatArray
    max_pyramid: FloatArray
    level_offset: IntArray
    level_ni: IntArray
    level_nj: IntArray

    @classmethod
    def from_heights(
        cls, heights: FloatArray, x0_m: float, y0_m: float, spacing_m: float
    ) -> HeightGrid:
        """Build the gradients and the maximum mipmap of ``heights`` (ni, nj >= 2)."""
        h = np.ascontiguousarray(heights, dtype=np.float64)
        if h.ndim != 2 or min(h.shape) < 2:
            raise ValueError(f"heights: need a 2-D grid of at least 2 x 2, got {h.shape}")
        grad_x, grad_y = np.gradient(h, spacing_m)
        cell_max = np.maximum(
            np.maximum(h[:-1, :-1], h[1:, :-1]), np.maximum(h[:-1, 1:], h[1:, 1:])
        )
        levels = [cell_max]
        while levels[-1].shape != (1, 1):
            levels.append(_halve_max(levels[-1]))
        sizes = np.array([lv.size for lv in levels], dtype=np.int64)
        return cls(
            heights=h,
            x0_m=float(x0_m),
            y0_m=float(y0_m),
            spacing_m=float(spacing_m),
            grad_x=np.ascontiguousarray(grad_x),
            grad_y=np.ascontiguousarray(grad_y),
            max_pyramid=np.concatenate([lv.reshape(-1) for lv in levels]),
            level_offset=np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(np.int64),
            level_ni=np.array([lv.shape[0] for lv in levels], dtype=np.int64),
            level_nj=np.array([lv.shape[1] for lv in levels], dtype=np.int64),
        )


def _halve_max(a: FloatArray) -> FloatArray:
    """Next mipmap level: the maximum over 2 x 2 blocks (odd edges padded with -inf)."""
    ni, nj = a.shape
    padded = np.full((ni + ni % 2, nj + nj % 2), -np.inf)
    padded[:ni, :nj] = a
    out: FloatArray = padded.reshape(padded.shape[0] // 2, 2, padded.shape[1] // 2, 2).max(
        axis=(1, 3)
    )
    return out


@kernel
def _patch_crossing(
    H: FloatArray,
    i: int,
    j: int,
    gx: float,
    gy: float,
    z: float,
    gdx: float,
    gdy: float,
    dz: float,
    ta: float,
    tb: float,
) -> float:
    """First ``t`` in ``[ta, tb]`` where the ray meets cell ``(i, j)``'s bilinear patch from
    above, or -1. The ray is ``(gx + t gdx, gy + t gdy)`` in grid units (cells) and
    ``z + t dz`` in metres. With ``u, v`` the in-cell fractions the patch is
    ``h00 + a u + b v + c u v``; along the ray ``u, v`` are linear in ``t``, so the ray's
    height above the patch is ``A w^2 + B w + C`` with ``w = t - ta``."""
    h00 = H[i, j]
    a = H[i + 1, j] - h00
    b = H[i, j + 1] - h00
    c = H[i + 1, j + 1] - H[i + 1, j] - H[i, j + 1] + h00
    u0 = gx + ta * gdx - i
    v0 = gy + ta * gdy - j
    C = z + ta * dz - (h00 + a * u0 + b * v0 + c * u0 * v0)
    if C <= 0.0:
        return ta  # already at or under the patch where the ray enters the cell
    B = dz - (a * gdx + b * gdy + c * (u0 * gdy + v0 * gdx))
    A = -c * gdx * gdy
    W = tb - ta
    root = math.inf
    if abs(A) * W <= 1e-12 * abs(B):
        if B < 0.0:
            root = -C / B
    else:
        disc = B * B - 4.0 * A * C
        if disc >= 0.0:
            q = -0.5 * (B + math.copysign(math.sqrt(disc), B))  # stable quadratic roots
            r1 = q / A
            r2 = C / q if q != 0.0 else math.inf
            if 0.0 <= r1 < root:
                root = r1
            if 0.0 <= r2 < root:
                root = r2
    if root <= W:
        return ta + root
    if C + W * (B + A * W) <= 0.0:  # under the patch at the exit: a root lost to rounding
        return tb
    return -1.0


@kernel
def _axis_span(g: float, gd: float, extent: float, t0: float, t1: float) -> tuple[float, float]:
    """Clip ``[t0, t1]`` to where ``g + t gd`` lies in ``[0, extent]`` (empty: t0 > t1)."""
    if gd != 0.0:
        ta = -g / gd
        tb = (extent - g) / gd
        return max(t0, min(ta, tb)), min(t1, max(ta, tb))
    if g < 0.0 or g > extent:
        return 1.0, 0.0
    return t0, t1


@kernel
def _exit_t(g: float, inv_gd: float, gd: float, cell: int, size: float) -> float:
    """Ray parameter where coordinate ``g + t gd`` leaves cell ``cell`` of size ``size``."""
    if gd > 0.0:
        return ((cell + 1) * size - g) * inv_gd
    if gd < 0.0:
        return (cell * size - g) * inv_gd
    return math.inf


@kernel
def cast_ray(
    o: FloatArray,
    d: FloatArray,
    t_min: float,
    t_max: float,
    H: FloatArray,
    s: float,
    pyramid: FloatArray,
    level_offset: IntArray,
    level_ni: IntArray,
    level_nj: IntArray,
) -> float:
    """Ray parameter of the first hit of ``o + t d`` (local frame, z up) with the height
    grid's surface for ``t`` in ``[t_min, t_max]``; -1 if it leaves the grid or the range
    first. ``d`` need not be a unit vector (``t`` is then in units of ``|d|``)."""
    ni, nj = H.shape
    gx, gy, z = o[0] / s, o[1] / s, o[2]  # grid units across, metres up
    gdx, gdy, dz = d[0] / s, d[1] / s, d[2]
    inv_gdx = 1.0 / gdx if gdx != 0.0 else 0.0
    inv_gdy = 1.0 / gdy if gdy != 0.0 else 0.0
    t0, t1 = _axis_span(gx, gdx, ni - 1.0, t_min, t_max)
    t0, t1 = _axis_span(gy, gdy, nj - 1.0, t0, t1)
    top = level_ni.shape[0] - 1
    top_max = pyramid[level_offset[top]]  # the highest point of the grid
    t = t0
    level = 0  # start at the coarsest level whose cell at the ray's start is below it
    while level < top:
        up = level + 1
        inv_up = 1.0 / float(1 << up)
        pi = min(max(math.floor((gx + t * gdx) * inv_up), 0), level_ni[up] - 1)
        pj = min(max(math.floor((gy + t * gdy) * inv_up), 0), level_nj[up] - 1)
        if z + t * dz <= pyramid[level_offset[up] + pi * level_nj[up] + pj]:
            break
        level = up
    while t < t1:
        if dz >= 0.0 and z + t * dz > top_max:
            return -1.0  # rising above everything: nothing left to hit
        size = float(1 << level)  # cells of this level, in grid units
        inv_size = 1.0 / size  # exact: a power of two
        n_j = level_nj[level]
        ci = min(max(math.floor((gx + t * gdx) * inv_size), 0), level_ni[level] - 1)
        cj = min(max(math.floor((gy + t * gdy) * inv_size), 0), n_j - 1)
        t_exit = min(t1, _exit_t(gx, inv_gdx, gdx, ci, size), _exit_t(gy, inv_gdy, gdy, cj, size))
        t_exit = max(t_exit, t)
        z_low = z + (t if dz >= 0.0 else t_exit) * dz  # lowest point: the ray is straight
        if z_low <= pyramid[level_offset[level] + ci * n_j + cj]:
            if level > 0:
                level -= 1  # something in this cell may reach the ray: look closer
                continue
            hit = _patch_crossing(H, ci, cj, gx, gy, z, gdx, gdy, dz, t, t_exit)
            if hit >= 0.0:
                return hit
        t = t_exit + _NUDGE_M  # past this cell
        if level < top:  # climb when the ray has left the parent cell: bigger steps
            half = 0.5 * inv_size
            if (
                math.floor((gx + t * gdx) * half) != ci >> 1
                or math.floor((gy + t * gdy) * half) != cj >> 1
            ):
                level += 1
    return -1.0


@kernel
def _slope_at(G: FloatArray, i: int, j: int, u: float, v: float) -> float:
    """Bilinear interpolation of the per-sample array ``G`` in cell ``(i, j)``."""
    g0: float = G[i, j] + u * (G[i + 1, j] - G[i, j])
    g1: float = G[i, j + 1] + u * (G[i + 1, j + 1] - G[i, j + 1])
    return g0 + v * (g1 - g0)


@kernel
def _terminator_lift_m(
    H: FloatArray, i: int, j: int, u: float, v: float, s: float, gx: float, gy: float
) -> float:
    """How far the bilinear facets may rise above the plane of the smooth shading normal
    ``(gx, gy)`` within about a cell: the gradient mismatch times the cell size.

    The smoothed normals light points whose own coarse facets face away from the Sun
    (the "shadow terminator" problem of interpolated normals): a shadow ray from the
    exact surface would then hit the neighbouring facet and cut hard-edged, cell-shaped
    shadows into the lit side of a rock. Starting the ray this much higher lets the
    smooth cosine shape the terminator, while on smooth ground (no mismatch) shadows
    still start at the surface."""
    h00 = H[i, j]
    twist = H[i + 1, j + 1] - H[i + 1, j] - H[i, j + 1] + h00
    hx = (H[i + 1, j] - h00 + v * twist) / s  # the patch's own slopes
    hy = (H[i, j + 1] - h00 + u * twist) / s
    mismatch = math.sqrt((gx - hx) ** 2 + (gy - hy) ** 2)
    return min(mismatch, TERMINATOR_LIFT_MAX_CELLS) * s


@kernel
def _segment_in_slab(w: float, dw: float, half: float, lo: float, hi: float) -> tuple[float, float]:
    """Clip ``[lo, hi]`` to where ``w + t dw`` lies in ``[-half, half]``."""
    if dw == 0.0:
        if abs(w) > half:
            return 1.0, 0.0
        return lo, hi
    ta = (-half - w) / dw
    tb = (half - w) / dw
    return max(lo, min(ta, tb)), min(hi, max(ta, tb))


@kernel
def rover_blocks(
    p_b: FloatArray,
    d_b: FloatArray,
    boxes_b: FloatArray,
    cylinders_b: FloatArray,
    bound_b: FloatArray,
) -> bool:
    """True if the ray ``p_b + t d_b``, ``t > 0`` (body frame), meets a rover part.

    ``boxes_b`` (n, 6): centre and half sizes of boxes aligned with the body axes.
    ``cylinders_b`` (m, 8): centre, unit axis, radius and half length of finite cylinders.
    ``bound_b`` (4,): centre and radius of a sphere enclosing all of them (a quick reject).
    """
    w0 = p_b[0] - bound_b[0]
    w1 = p_b[1] - bound_b[1]
    w2 = p_b[2] - bound_b[2]
    along = w0 * d_b[0] + w1 * d_b[1] + w2 * d_b[2]  # d_b is a unit vector
    closest_t = max(-along, 0.0)
    gap2 = (w0 + closest_t * d_b[0]) ** 2 + (w1 + closest_t * d_b[1]) ** 2
    if gap2 + (w2 + closest_t * d_b[2]) ** 2 > bound_b[3] ** 2:
        return False
    for k in range(boxes_b.shape[0]):
        lo, hi = 0.0, math.inf
        for a in range(3):
            lo, hi = _segment_in_slab(p_b[a] - boxes_b[k, a], d_b[a], boxes_b[k, 3 + a], lo, hi)
        if lo <= hi:
            return True
    for k in range(cylinders_b.shape[0]):
        w = p_b - cylinders_b[k, 0:3]
        axis = cylinders_b[k, 3:6]
        radius = cylinders_b[k, 6]
        w_ax = w[0] * axis[0] + w[1] * axis[1] + w[2] * axis[2]
        d_ax = d_b[0] * axis[0] + d_b[1] * axis[1] + d_b[2] * axis[2]
        w_perp = w - w_ax * axis
        d_perp = d_b - d_ax * axis
        A = d_perp[0] ** 2 + d_perp[1] ** 2 + d_perp[2] ** 2
        B = 2.0 * (w_perp[0] * d_perp[0] + w_perp[1] * d_perp[1] + w_perp[2] * d_perp[2])
        C = w_perp[0] ** 2 + w_perp[1] ** 2 + w_perp[2] ** 2 - radius * radius
        lo, hi = 0.0, math.inf
        if A < 1e-15:  # ray parallel to the axis: inside the tube or never
            if C > 0.0:
                continue
        else:
            disc = B * B - 4.0 * A * C
            if disc < 0.0:
                continue
            sq = math.sqrt(disc)
            lo = max(lo, (-B - sq) / (2.0 * A))
            hi = min(hi, (-B + sq) / (2.0 * A))
        lo, hi = _segment_in_slab(w_ax, d_ax, cylinders_b[k, 7], lo, hi)
        if lo <= hi:
            return True
    return False


@parallel_kernel
def render_eyes(
    f_px: float,
    c_u_px: float,
    c_v_px: float,
    R_l_cam: FloatArray,
    eyes_l: FloatArray,
    row_stride: int,
    head_l: FloatArray,
    t_max: float,
    H: FloatArray,
    s: float,
    grad_x: FloatArray,
    grad_y: FloatArray,
    pyramid: FloatArray,
    level_offset: IntArray,
    level_ni: IntArray,
    level_nj: IntArray,
    sun_l: FloatArray,
    shadows: bool,
    R_b_l: FloatArray,
    rover_l: FloatArray,
    boxes_b: FloatArray,
    cylinders_b: FloatArray,
    bound_b: FloatArray,
    out_range: FloatArray,
    out_depth: FloatArray,
    out_x: FloatArray,
    out_y: FloatArray,
    out_direct: FloatArray,
    out_sky_view: FloatArray,
    out_footprint: FloatArray,
) -> None:
    """Cast every pixel's ray of the eyes and shade its ground point (local frame, z up).

    Pixel ``(row, col)`` of eye ``e`` looks along ``R_l_cam @ ((col - c_u)/f, (row - c_v)/f,
    1)`` from ``eyes_l[e]`` (the eyes share the orientation). The rows of all eyes are cast
    in one parallel loop, in the order ``row = (j * row_stride) % height`` (``row_stride``
    prime to the height: every row once), so that each thread's share of the loop spreads
    over the image, near ground and far alike, and the threads finish together; a pixel's
    values do not depend on the order. Outputs (eyes, height, width): ``out_range``
    distance to the hit (m) and
    ``out_depth`` its camera ``z`` (NaN where the ray meets nothing); ``out_x, out_y`` the
    hit in the grid's local frame; ``out_direct`` the direct-sun factor ``max(n.sun, 0)``
    times the visibility of the Sun (0 in shadow); ``out_sky_view`` ``(1 + n_up) / 2``, the
    fraction of the sky a facet sees; ``out_footprint`` the pixel's size on the ground (m),
    ``distance / (f sqrt(cos))`` with the distance and the incidence ``cos`` of the line of
    sight seen from ``head_l`` (the rig's midpoint, so that both eyes band-limit the
    texture of a ground point alike; the cosine floored at 0.1). Rover parts (``boxes_b``,
    ``cylinders_b``; empty for no rover shadow) and their bounding sphere ``bound_b`` are in
    the body frame:
    ``p_b = R_b_l @ (p_l - rover_l)``.
    """
    n_eyes, height, width = out_range.shape
    ni, nj = H.shape
    for n in numba.prange(n_eyes * height):
        e = n % n_eyes
        row = (n // n_eyes) * row_stride % height
        eye_l = eyes_l[e]
        d = np.empty(3)
        p = np.empty(3)
        p_b = np.empty(3)
        sun_b = np.empty(3)
        for col in range(width):
            xc = (col - c_u_px) / f_px
            yc = (row - c_v_px) / f_px
            inv_norm = 1.0 / math.sqrt(xc * xc + yc * yc + 1.0)
            for a in range(3):
                d[a] = (R_l_cam[a, 0] * xc + R_l_cam[a, 1] * yc + R_l_cam[a, 2]) * inv_norm
            t = cast_ray(eye_l, d, 0.0, t_max, H, s, pyramid, level_offset, level_ni, level_nj)
            if t < 0.0:
                out_range[e, row, col] = np.nan
                out_depth[e, row, col] = np.nan
                out_x[e, row, col] = np.nan
                out_y[e, row, col] = np.nan
                out_direct[e, row, col] = 0.0
                out_sky_view[e, row, col] = 0.0
                out_footprint[e, row, col] = 0.0
                continue
            for a in range(3):
                p[a] = eye_l[a] + t * d[a]
            i = min(max(math.floor(p[0] / s), 0), ni - 2)
            j = min(max(math.floor(p[1] / s), 0), nj - 2)
            u = p[0] / s - i
            v = p[1] / s - j
            gx = _slope_at(grad_x, i, j, u, v)
            gy = _slope_at(grad_y, i, j, u, v)
            inv_n = 1.0 / math.sqrt(gx * gx + gy * gy + 1.0)  # normal (-gx, -gy, 1) / |.|
            cos_sun = (sun_l[2] - gx * sun_l[0] - gy * sun_l[1]) * inv_n
            direct = 0.0
            if cos_sun > 0.0:
                direct = cos_sun
                p[2] += SHADOW_LIFT_M + _terminator_lift_m(H, i, j, u, v, s, gx, gy)
                if shadows:
                    t_sun = cast_ray(
                        p, sun_l, 0.0, math.inf, H, s, pyramid, level_offset, level_ni, level_nj
                    )
                    if t_sun >= 0.0:
                        direct = 0.0
                if direct > 0.0 and boxes_b.shape[0] + cylinders_b.shape[0] > 0:
                    for a in range(3):
                        p_b[a] = 0.0
                        sun_b[a] = 0.0
                        for k in range(3):
                            p_b[a] += R_b_l[a, k] * (p[k] - rover_l[k])
                            sun_b[a] += R_b_l[a, k] * sun_l[k]
                    if rover_blocks(p_b, sun_b, boxes_b, cylinders_b, bound_b):
                        direct = 0.0
            out_range[e, row, col] = t
            out_depth[e, row, col] = t * inv_norm
            out_x[e, row, col] = eye_l[0] + t * d[0]
            out_y[e, row, col] = eye_l[1] + t * d[1]
            out_direct[e, row, col] = direct
            out_sky_view[e, row, col] = 0.5 * (1.0 + inv_n)
            to_head_x = head_l[0] - p[0]
            to_head_y = head_l[1] - p[1]
            to_head_z = head_l[2] - p[2]
            dist = math.sqrt(to_head_x**2 + to_head_y**2 + to_head_z**2)
            cos_head = (to_head_z - gx * to_head_x - gy * to_head_y) * inv_n / dist
            out_footprint[e, row, col] = dist / (f_px * math.sqrt(max(cos_head, 0.1)))
