"""Measurements taken on the NURBS surface itself (not on the scan).

The surface is tessellated densely (0.5 degree x ~0.5 mm) and cut by the planes
z = h of the calf frame with the same multi-plane slicer as the scans
(:func:`app.geometry.sections.mesh_section_segments`).  Each cut gives the contour's
perimeter and the perimeter of its convex hull - the tape-measure girth that hosiery
standards and ANSUR use.  Works for any stored surface, also imported ones whose rings
are not planar.  Units: mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull

from app.geometry.sections import mesh_section_segments
from app.geometry.spline.nurbs import NurbsSurface, evaluate_grid
from app.geometry.spline.tessellation import surface_grid_faces, tessellate


@dataclass(frozen=True)
class Girth:
    height_mm: float
    circumference_mm: float  # perimeter of the section
    tape_mm: float  # perimeter of its convex hull


def surface_height_range(surface: NurbsSurface) -> tuple[float, float]:
    """Lowest and highest z of the surface (its first and last rings), mm."""
    vertices, _ = tessellate(surface, 72, 2)
    z = vertices[:, 2]
    return float(z.min()), float(z.max())


#: rows of the dense tessellation cut at a time (720 x 129 vertices, ~2 MB): the memory of
#: a measurement does not grow with the height of the surface
ROWS_PER_CHUNK = 128


def girths(surface: NurbsSurface, heights: np.ndarray, n_around: int = 720) -> list[Girth]:
    """Girths of the surface at calf-frame heights (k,) mm; NaN where the plane misses.

    The surface is tessellated ``n_around`` x one row per 0.5 mm and cut chunk by chunk
    of :data:`ROWS_PER_CHUNK` rows (each triangle lies in exactly one chunk, so a plane
    that crosses two chunks gets its segments from both): bounded memory for any height.
    """
    heights = np.asarray(heights, dtype=np.float64)
    z0, z1 = surface_height_range(surface)
    n_along = max(int(np.ceil((z1 - z0) * 2)) + 1, 8)
    # planes exactly on the end rings are nudged inside by a micrometre
    planes = np.clip(heights, z0 + 1e-3, z1 - 1e-3)
    order = np.argsort(planes)
    sorted_planes = planes[order]
    u0, u1 = surface.domain_u
    v0, v1 = surface.domain_v
    u = u0 + (u1 - u0) * np.arange(n_around) / n_around
    v = np.linspace(v0, v1, n_along)
    pieces: list[tuple[np.ndarray, np.ndarray]] = []
    full_chunk_faces = surface_grid_faces(n_around, ROWS_PER_CHUNK + 1)
    for start in range(0, n_along - 1, ROWS_PER_CHUNK):
        rows = v[start:min(start + ROWS_PER_CHUNK, n_along - 1) + 1]
        faces = full_chunk_faces if len(rows) == ROWS_PER_CHUNK + 1 else surface_grid_faces(n_around, len(rows))
        vertices = evaluate_grid(surface, u, rows).reshape(-1, 3)
        low = np.searchsorted(sorted_planes, vertices[:, 2].min(), side="left")
        high = np.searchsorted(sorted_planes, vertices[:, 2].max(), side="right")
        if high <= low:
            continue
        plane, segments = mesh_section_segments(vertices, faces, sorted_planes[low:high])
        pieces.append((plane + low, segments))
    plane = np.concatenate([p for p, _ in pieces]) if pieces else np.empty(0, dtype=np.int64)
    segments = np.concatenate([s for _, s in pieces]) if pieces else np.empty((0, 2, 2))
    out: list[Girth | None] = [None] * len(heights)
    lengths = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
    perimeters = np.bincount(plane, weights=lengths, minlength=len(heights))
    for rank, index in enumerate(order):
        points = segments[plane == rank].reshape(-1, 2)
        if len(points) < 3 or heights[index] < z0 - 1e-6 or heights[index] > z1 + 1e-6:
            out[index] = Girth(float(heights[index]), float("nan"), float("nan"))
            continue
        hull = ConvexHull(points)
        out[index] = Girth(float(heights[index]), float(perimeters[rank]), float(hull.area))
    return out  # type: ignore[return-value]
