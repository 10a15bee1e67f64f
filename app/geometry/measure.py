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

from app.geometry.exchange import tessellate
from app.geometry.nurbs import NurbsSurface
from app.geometry.sections import mesh_section_segments


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


def girths(surface: NurbsSurface, heights: np.ndarray, n_around: int = 720) -> list[Girth]:
    """Girths of the surface at calf-frame heights (k,) mm; NaN where the plane misses."""
    heights = np.asarray(heights, dtype=np.float64)
    z0, z1 = surface_height_range(surface)
    n_along = max(int(np.ceil((z1 - z0) * 2)) + 1, 8)
    vertices, faces = tessellate(surface, n_around, n_along)
    # planes exactly on the end rings are nudged inside by a micrometre
    planes = np.clip(heights, z0 + 1e-3, z1 - 1e-3)
    order = np.argsort(planes)
    plane, segments = mesh_section_segments(vertices, faces, planes[order])
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
