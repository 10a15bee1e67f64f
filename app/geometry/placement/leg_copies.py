"""Copies of one leg in a scan, and which of them is the skin.

A mesh can hold one leg more than once as detached pieces, each placed as a whole leg
(ankle, calf, knee waist) by :mod:`app.geometry.placement.place`:

- the passes of a scanner exported unmerged, or a leg that moved between them: shells
  that cross each other, a few mm apart - the copy with the most points is measured;
- a hollowed or thickened mesh (a shell given a wall for 3D printing, a solidify
  modifier, an inner wall a reconstruction left): a second surface wholly inside the
  first.  A scanner sees the skin from outside, so a surface inside another is no skin
  it saw: the outer one is measured, whatever the point counts (a solidify copies every
  vertex, so the counts tie, and the inner wall read every girth 2 pi times the wall's
  thickness short - 13 mm for a 2 mm wall - with a warning that named the copies "0 mm
  apart").

Nesting is read at the calf maximum C, where the limb's taper is least: the inner copy's
points within :data:`NEST_SLAB_MM` of C's height lie inside the convex hull of the outer's
there (a tape round the outer reaches round the inner), and most of the outer's lie
outside the inner's.  Two crossing passes fail it: each holds about half of the other.

Frame: each copy's calf frame (mm, z up the calf axis from B); points (n, 3) scan mm.
"""

from __future__ import annotations

from typing import Protocol, TypeVar

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, Delaunay, QhullError

#: two legs whose ankles (B's centres) and calf maxima (C's centres) both lie closer than
#: this are one leg scanned twice, mm: two legs cannot interpenetrate, so two people's or
#: one person's two legs have their centres at least two section radii apart, and the
#: thinnest ankle's radius is 25 mm (ANSUR II's least ankle girth, 156 mm, over 2 pi)
SAME_LEG_MM = 25.0
#: the slab about C in which nesting is read, mm either side: thick enough to hold a
#: coarse mesh's rings (the corpus's coarsest tessellation has edges up to 34 mm p95, its
#: vertices ~8 mm apart along the leg), thin enough that the calf's taper across it
#: (C is its maximum: the girth is level there) stays under a wall's thickness
NEST_SLAB_MM = 10.0
#: nested: at least this share of the inner copy's slab inside the outer's hull ...
INSIDE_SHARE = 0.95
#: ... and at most this share of the outer's inside the inner's (two crossing passes of
#: one leg hold about half of each other's points)
CROSSING_SHARE = 0.5
#: a slab needs this many points for a hull to stand for its section
MIN_SLAB_POINTS = 12


class LegCopy(Protocol):
    """A placed piece of the scan: its points (n, 3), scan mm."""

    points: np.ndarray
    n_points: int


class CopyPlacement(Protocol):
    """Where a copy's calf is: B's centre and the calf axis (scan mm), C's height on it."""

    origin_mm: np.ndarray
    rotation: np.ndarray
    c_mm: float

    @property
    def frame(self): ...  # CalfFrame: to_calf((n, 3) scan mm) -> (n, 3) calf-frame mm


Placed = TypeVar("Placed", bound=tuple)


def nested_depth(inner: np.ndarray, outer: np.ndarray, outer_placement: CopyPlacement) -> float | None:
    """How far the copy ``inner`` (n, 3) lies inside the copy ``outer`` (m, 3), scan mm,
    at the outer's calf maximum: the difference of the two tape girths (convex-hull
    perimeters of the slabs) over 2 pi, mm; None when ``inner`` is not nested in ``outer``
    (module docstring) or a slab holds too few points to tell."""
    frame = outer_placement.frame
    slabs = []
    for points in (inner, outer):
        local = frame.to_calf(points)
        slab = local[np.abs(local[:, 2] - outer_placement.c_mm) <= NEST_SLAB_MM, :2]
        if len(slab) < MIN_SLAB_POINTS:
            return None
        slabs.append(slab)
    try:
        hulls = [ConvexHull(slab) for slab in slabs]
        regions = [Delaunay(slab[hull.vertices]) for slab, hull in zip(slabs, hulls)]
    except QhullError:  # a slab's points on a line: no section to compare
        return None
    inner_inside = float(np.mean(regions[1].find_simplex(slabs[0]) >= 0))
    outer_inside = float(np.mean(regions[0].find_simplex(slabs[1]) >= 0))
    if inner_inside < INSIDE_SHARE or outer_inside > CROSSING_SHARE:
        return None
    # in 2-D, "area" is the perimeter; a convex set inside another is no longer round (5%
    # of the points may stray past the outer hull: not below 0)
    return max(float(hulls[1].area - hulls[0].area) / (2.0 * np.pi), 0.0)


def one_copy_per_leg(legs: list[Placed]) -> tuple[list[Placed], list[str]]:
    """The legs found with each leg once, and what was set aside, in words.

    ``legs``: (copy, placement) pairs (:class:`LegCopy`, :class:`CopyPlacement`).  Two are
    copies of one leg when their B centres and their C centres (B + C's height along the
    calf axis) are both within :data:`SAME_LEG_MM`; copies of copies are one leg too (the
    graph's connected components).  Of each leg's copies, those nested inside another
    are set aside (module docstring), and of the rest the one with the most points is
    measured; calling them two legs would ask for a side that does not exist.
    """
    centres = np.array([[p.origin_mm, np.asarray(p.origin_mm) + p.c_mm * np.asarray(p.rotation)[2]] for _, p in legs])
    apart = np.linalg.norm(centres[:, None] - centres[None, :], axis=-1).max(axis=-1)  # (n, n) the farther of B, C
    n_groups, copy_of = connected_components(csr_matrix(apart < SAME_LEG_MM), directed=False)
    kept, warnings = [], []
    for group in range(n_groups):  # a few legs
        members = np.flatnonzero(copy_of == group).tolist()
        depths: dict[int, float] = {}  # inner copy -> how far inside another it lies, mm
        for inner in members:
            for outer in members:
                depth = None if inner == outer else nested_depth(legs[inner][0].points, legs[outer][0].points,
                                                                 legs[outer][1])
                if depth is not None:
                    depths[inner] = max(depth, depths.get(inner, 0.0))
        skins = [m for m in members if m not in depths] or members
        best = max(skins, key=lambda m: legs[m][0].n_points)
        kept.append(legs[best])
        if depths:
            walls = sorted(depths.values())
            what = "a second surface" if len(walls) == 1 else f"{len(walls)} more surfaces"
            warnings.append(
                f"the scan holds {what} {walls[0]:.1f}" + (f"-{walls[-1]:.1f}" if len(walls) > 1 else "")
                + " mm inside the skin (a mesh hollowed or given a wall, as for 3D printing): the leg was measured on "
                "the outer surface, the skin a scanner sees; export the scan itself if it is not")
        others = [m for m in skins if m != best]
        if others:
            offset = max(float(apart[best, m]) for m in others)
            warnings.append(
                f"the scan holds this leg {len(others) + 1} times, up to {offset:.0f} mm apart (the passes of a "
                "scanner exported without being merged, or the leg moved between them): it was measured on the copy "
                f"with the most points ({legs[best][0].n_points} of {sum(legs[m][0].n_points for m in skins)}); "
                "export the merged scan, or scan again standing still, if the copies differ")
    return kept, warnings
