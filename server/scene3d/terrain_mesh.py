"""The 3D view's terrain drawn as terrain looks: a grid mesh with a colour per vertex, the
surface's albedo times a hillshade, for viser's ``add_mesh_trimesh``.

- **Hillshade**: Lambert's cosine of the surface normal with a fixed light, the cartographer's
  hill shading (Horn 1981): ``shade = max(0, n · l)`` with ``l`` from the North-West
  (azimuth ``LIGHT_AZIMUTH_DEG`` clockwise from North), ``LIGHT_ELEVATION_DEG`` up, the normal
  from central differences of the heights. A vertex's brightness is
  ``AMBIENT + (1 - AMBIENT) shade``, so a slope turned away from the light stays visible.
  A fixed light, not the Sun: relief reads the same at any hour (the sun arrow shows the Sun).
- **Colour**: the Mars soil colour ``SOIL_RGB`` (at albedo 0.25) scaled by ``albedo / 0.25``
  and by the brightness, clipped to 8 bits.
- **The ground's map** (``ground_mesh``): the cells of a ``GroundMap`` within ``half_m`` of a
  centre, one vertex per cell centre at its height and albedo.
- **The truth** (``terrain_patch``, truth view only): the simulator's terrain sampled every
  ``TERRAIN_STEP_M`` around a centre, each vertex's albedo the mean of four points around it
  (one point would alias the texture's millimetre grain into a checkerboard).

Coordinates: the mission frame (x North, y East, z Down; m); the faces wind so that their
normals point up (-z).
"""

from __future__ import annotations

import math

import numpy as np
import trimesh
from numpy.typing import NDArray

from server.terrain.ground_map import GroundMap
from sim.world.terrain import Terrain

FloatArray = NDArray[np.float64]

TERRAIN_HALF_M = 16.0  # a patch reaches this far from its centre
TERRAIN_STEP_M = 0.16  # the truth's grid spacing: 201 x 201 vertices
SOIL_RGB = np.array([178.0, 118.0, 82.0])  # Gusev/Meridiani ochre at albedo 0.25
LIGHT_AZIMUTH_DEG = 315.0  # from the North-West, as maps are hill-shaded
LIGHT_ELEVATION_DEG = 45.0
AMBIENT = 0.35


def terrain_note(pairs: int) -> str:
    """What the view's terrain is, for its viewers: the ground's map and what refined it."""
    refined = f"{pairs} stereo pair{'s' if pairs != 1 else ''}" if pairs else "no stereo yet"
    return f"Terrain: the ground's map (orbital DEM, {refined})"


def hillshade(height_up_m: FloatArray, step_m: float) -> FloatArray:
    """``max(0, n · l)`` per grid point (module docstring); rows along North, columns East."""
    dh_dn, dh_de = np.gradient(np.asarray(height_up_m, dtype=np.float64), step_m)
    az, el = math.radians(LIGHT_AZIMUTH_DEG), math.radians(LIGHT_ELEVATION_DEG)
    light = (math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el))  # N, E, Up
    norm = np.sqrt(dh_dn**2 + dh_de**2 + 1.0)
    dot = (-dh_dn * light[0] - dh_de * light[1] + light[2]) / norm
    out: FloatArray = np.clip(dot, 0.0, 1.0)
    return out


def vertex_rgb(albedo: FloatArray, shade: FloatArray) -> NDArray[np.uint8]:
    """8-bit colours (..., 3) of vertices of ``albedo`` under ``shade`` (module docstring)."""
    brightness = AMBIENT + (1.0 - AMBIENT) * np.asarray(shade, dtype=np.float64)
    scale = (np.asarray(albedo, dtype=np.float64) / 0.25 * brightness)[..., None]
    return np.asarray(np.clip(SOIL_RGB * scale, 0.0, 255.0), dtype=np.uint8)


def grid_mesh(
    north_m: FloatArray, east_m: FloatArray, height_up_m: FloatArray, albedo: FloatArray
) -> trimesh.Trimesh:
    """A mesh over a regular grid (rows along North): vertices ``(n, e, -h)`` in the mission
    frame, two up-facing triangles per grid square, hill-shaded albedo colours."""
    ni, nj = height_up_m.shape
    step = float(north_m[1] - north_m[0]) if ni > 1 else 1.0
    gn, ge = np.meshgrid(north_m, east_m, indexing="ij")
    vertices = np.stack([gn.ravel(), ge.ravel(), -np.asarray(height_up_m).ravel()], axis=1)
    idx = np.arange(ni * nj).reshape(ni, nj)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[:-1, 1:], idx[1:, 1:]
    # x North, y East, z Down: (a, c, b) turns from North to East, its normal along -z (up)
    faces = np.concatenate(
        [np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)]
    )
    rgb = vertex_rgb(albedo, hillshade(height_up_m, step)).reshape(-1, 3)
    colours = np.concatenate([rgb, np.full((rgb.shape[0], 1), 255, np.uint8)], axis=1)
    return trimesh.Trimesh(
        vertices=vertices.astype(np.float32), faces=faces, vertex_colors=colours, process=False
    )


def ground_mesh(
    ground: GroundMap, centre_w: FloatArray, half_m: float = TERRAIN_HALF_M
) -> trimesh.Trimesh:
    """The ground's map around ``centre_w`` (mission x, y), within ``half_m`` (clipped to the
    map; at least a 2 x 2 block of cells)."""
    ny, nx = ground.shape
    i_c, j_c = ground.cell_of(np.asarray(centre_w[0]), np.asarray(centre_w[1]))
    k = max(1, round(half_m / ground.cell_m))
    i0 = int(np.clip(round(float(i_c)) - k, 0, ny - 2))
    j0 = int(np.clip(round(float(j_c)) - k, 0, nx - 2))
    i1 = int(np.clip(round(float(i_c)) + k + 1, i0 + 2, ny))
    j1 = int(np.clip(round(float(j_c)) + k + 1, j0 + 2, nx))
    north = np.asarray(ground.north0_m + ground.cell_m * np.arange(i0, i1), np.float64)
    east = np.asarray(ground.east0_m + ground.cell_m * np.arange(j0, j1), np.float64)
    return grid_mesh(north, east, ground.height_m[i0:i1, j0:j1], ground.albedo[i0:i1, j0:j1])


def terrain_patch(
    terrain: Terrain, centre_w: FloatArray, origin_world: FloatArray
) -> trimesh.Trimesh:
    """The simulator's terrain (the truth) around ``centre_w`` (mission x, y):
    ``origin_world`` the mission frame's origin in the simulator's frame."""
    n = round(2 * TERRAIN_HALF_M / TERRAIN_STEP_M) + 1
    offsets = np.linspace(-TERRAIN_HALF_M, TERRAIN_HALF_M, n)
    north, east = centre_w[0] + offsets, centre_w[1] + offsets
    gn, ge = np.meshgrid(north + origin_world[0], east + origin_world[1], indexing="ij")
    height = np.asarray(terrain.height_m(gn, ge), dtype=np.float64) + origin_world[2]
    quarter = (-0.25 * TERRAIN_STEP_M, 0.25 * TERRAIN_STEP_M)
    albedo = np.mean(
        [np.asarray(terrain.albedo(gn + dn, ge + de)) for dn in quarter for de in quarter], axis=0
    )
    return grid_mesh(north, east, height, albedo)
