"""The tape's loops on the foot's planes (app.geometry.anatomy.foot reads cA and cY on
them): a plane's section of the scan, whether it closes round a loop a tape can be read
on, the tape girth of the loop and how much longer the skin may be than it.

Arrays: points (n, 3) and the in-plane sections (n, 2), mm; faces (f, 3) or None (a
cloud, whose sections are read on its neighbour graph's edges (e, 2)).

- **A cloud's sections** are read on its neighbour graph
  (:mod:`app.geometry.sections.cloud_edges`): where the edges between mutual nearest
  neighbours cross the plane.  A slab of points projected onto the plane read cY up to
  15 mm long and cA up to 4 mm short on a body mesh's vertices (0.4-11 mm apart on one
  foot), and a scanner's floor strays into cA 17 mm long.
- **A sparse loop** says what it may miss.  A tape's loop read from a cloud's crossings
  is short where the cloud is sparse, two ways: its hull's chords bridge the gaps between
  crossings (a body mesh's 700 vertices on a whole leg left the sole of the forefoot
  without a crossing over 60 mm), and each crossing lies on its edge's chord, inside the
  skin by t (1 - t) e^2 / 2 times the skin's curvature (e the edge, t where on it).  Real
  legs read as 4,000-8,000 of their vertices read cA up to 34 mm and cY up to 15 mm short
  of their meshes and said nothing (benchmarks/real_samples.py).  What the chords may
  miss is bounded: a convex curve through the hull's vertices lies, over each edge, in
  the triangle the edge makes with its neighbouring edges continued (the curve turns
  the same way throughout), above the floor (the lower of the sole and the foot's lowest
  skin: a standing forefoot lies within 12 mm of the heel's floor) - :func:`chord_excess`,
  the triangles' two sides less the edge, summed.  The crossings' depth is estimated at
  the loop's mean curvature, 2 pi / girth (exact on average round a closed convex curve),
  and shortens the tape by 2 pi times it.  Their sum, over the tape's band (median), is
  the girth's ``uncertainty_mm`` when more than GIRTH_TOLERANCE_MM (an order's 3 mm), with
  a warning to take it by tape.  On a mesh it is 0.4-0.9 mm; on the generated legs'
  re-scans (benchmarks/chart_accuracy.py 8 11) it stays within the tolerance on every cA
  and on 118 of 119 cY readings; on the real legs read as sparse clouds it reaches every
  error past the tolerance but one, 0.3 mm short (benchmarks/real_samples.py).  It is a bound, not
  a correction, and a loose one: each edge's turn counts in full at both its ends, about
  12 times what a smooth arc's chords miss (0.3 mm round a 36-gon), 5 times over a
  90-degree gap - so a sparse cloud is warned about before it is wrong, never after.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, cKDTree

from app.geometry.anatomy.level_points import GIRTH_TOLERANCE_MM
from app.geometry.anatomy.level_runs import running_median
from app.geometry.sections import (
    crossing_ends,
    largest_gap,
    mesh_section_segments,
    neighbour_edges,
    project_on_local_quadratics,
)

#: the widest run of empty angle bins a loop may have, degrees (0.3 of the turn: a hole,
#: the flat sole the floor's removal took - 80-110 degrees round the forefoot's centre -
#: which the tape bridges; wider is no closed section).  Bins left empty one here and one
#: there are the sampling's (about 3 points a bin: e^-3, 5%, of them empty), not a gap
LOOP_MAX_GAP_DEG = 108.0


def cloud_graph(points: np.ndarray, faces: np.ndarray | None) -> tuple[np.ndarray | None, cKDTree | None]:
    """A cloud's neighbour graph (e, 2) its sections are read on
    (:func:`app.geometry.sections.neighbour_edges`) and the k-d tree it was built on (the
    heel's corner asks the same points which are skin); (None, None) for a mesh (its
    sections are exact)."""
    if faces is not None and len(faces):
        return None, None
    tree = cKDTree(points) if len(points) else None
    return neighbour_edges(points, tree=tree), tree


def plane_sections(points: np.ndarray, faces: np.ndarray | None, edges: np.ndarray | None, origin: np.ndarray,
                   basis: np.ndarray, offsets: np.ndarray) -> list[np.ndarray]:
    """The sections (n_k, 2) of the planes {p : (p - origin) . basis[2] = offset},
    ``offsets`` (k,) ascending, in the in-plane coordinates basis[0], basis[1] (basis (3, 3)
    orthonormal rows): a mesh's exact plane-section segment ends
    (:func:`app.geometry.sections.mesh_section_segments`), a cloud's crossings of its
    neighbour graph's ``edges`` (e, 2) (:func:`app.geometry.sections.edge_crossings`)."""
    return loop_sections(points, faces, edges, origin, basis, offsets)[0]


def loop_sections(points: np.ndarray, faces: np.ndarray | None, edges: np.ndarray | None, origin: np.ndarray,
                  basis: np.ndarray, offsets: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """:func:`plane_sections` and, per plane, its chord sag (k,) mm^2: the mean over its
    crossings of t (1 - t) e^2 / 2 (e the crossing's edge length, t where along it the
    plane lies) - times the skin's curvature, how far inside the skin a crossing on the
    edge's chord lies (module docstring, "A sparse loop"); 0 for a mesh, whose sections
    are exact.  One pass over the edges for both."""
    q = (points - origin) @ basis.T
    if faces is not None and len(faces):
        plane, segments = mesh_section_segments(q, faces, offsets)
        return [segments[plane == k].reshape(-1, 2) for k in range(len(offsets))], np.zeros(len(offsets))
    if edges is None:
        raise ValueError("a cloud's sections are read on its neighbour graph: pass its edges")
    plane, _, a, b, t = crossing_ends(q, edges, offsets)  # as edge_crossings reads them
    crossings = a[:, :2] + t[:, None] * (b[:, :2] - a[:, :2])
    sag = t * (1.0 - t) * np.sum((b - a) ** 2, axis=1) / 2.0
    count = np.bincount(plane, minlength=len(offsets))
    sags = np.bincount(plane, sag, minlength=len(offsets)) / np.maximum(count, 1)
    return [crossings[plane == k] for k in range(len(offsets))], sags


def closed_loop(section: np.ndarray) -> bool:
    """Whether a section's points (n, 2) close round a loop a tape can be read on: 30 or
    more points, and no run of empty bins of angle round their centroid (about 3 points
    a bin, 36-360 bins) wider than LOOP_MAX_GAP_DEG.  A narrower gap is bridged by the
    hull's straight chord, as a tape bridges it: a sole the floor's removal took off (the
    plantar forefoot is flat and ~80 mm wide, so it leaves one wide gap) is the flat the
    foot stood on."""
    if len(section) < 30:
        return False
    rel = section - section.mean(axis=0)
    angle = np.arctan2(rel[:, 1], rel[:, 0])
    bins = int(np.clip(len(section) // 3, 36, 360))  # ~3 points a bin: a sparse ring gets wider bins
    index = np.minimum(((angle + np.pi) * (bins / (2 * np.pi))).astype(np.int64), bins - 1)
    filled = np.bincount(index, minlength=bins) > 0
    return bool(largest_gap(filled[None])[0][0] <= LOOP_MAX_GAP_DEG)


def hull_girths(sections: list[np.ndarray]) -> np.ndarray:
    """(k,) mm: the convex hull of each section's points as they are, NaN where not
    :func:`closed_loop` - the ranking of planes the tape is then read on (:func:`extreme_tape`:
    a scanner's noise widens each by about as much, so the planes keep their order)."""
    return np.array([ConvexHull(section).area if closed_loop(section) else np.nan for section in sections])


def chord_excess(loop: np.ndarray, floor_gradient: np.ndarray, floor_level: float) -> float:
    """How much longer (mm) than its convex hull's perimeter a convex curve through the
    hull's vertices can be: the bound of the module docstring's "A sparse loop", summed
    over the hull's edges; inf where an edge's neighbouring edges, continued, meet
    neither beyond it nor the floor (the loop turns half round over it: no bound).
    ``loop`` (n, 2) in-plane mm; the skin lies on the floor or above it: in-plane points
    p with ``floor_gradient`` (2,) . p >= ``floor_level`` (mm)."""
    vertices = loop[ConvexHull(loop).vertices]  # counter-clockwise
    a, b = vertices, np.roll(vertices, -1, axis=0)
    ahead = a - np.roll(vertices, 1, axis=0)  # the edge before a, continued past a
    back = b - np.roll(vertices, -2, axis=0)  # the edge after b, continued back past b
    chord = b - a
    # a + s ahead = b + t back
    det = back[:, 0] * ahead[:, 1] - ahead[:, 0] * back[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (back[:, 0] * chord[:, 1] - chord[:, 0] * back[:, 1]) / det
        t = (ahead[:, 0] * chord[:, 1] - chord[:, 0] * ahead[:, 1]) / det
    meets = np.isfinite(s) & np.isfinite(t) & (s >= 0) & (t >= 0)
    apex = a + np.where(meets, s, 0.0)[:, None] * ahead
    over = np.linalg.norm(apex - a, axis=1) + np.linalg.norm(apex - b, axis=1)
    # where the corner lies below the floor (or, the edges not meeting, both run down to
    # it), the curve is bounded by the floor between where they reach it
    level_a = np.maximum(a @ floor_gradient, floor_level)
    level_b = np.maximum(b @ floor_gradient, floor_level)
    descent_a, descent_b = -(ahead @ floor_gradient), -(back @ floor_gradient)
    down = (descent_a > 0) & (descent_b > 0)
    floored = down & (~meets | (apex @ floor_gradient < floor_level))
    if not (meets | floored).all():
        return float("inf")
    if floored.any():
        enter = a + ((level_a - floor_level) / np.where(down, descent_a, 1.0))[:, None] * ahead
        leave = b + ((level_b - floor_level) / np.where(down, descent_b, 1.0))[:, None] * back
        along_floor = (np.linalg.norm(enter - a, axis=1) + np.linalg.norm(leave - enter, axis=1)
                       + np.linalg.norm(b - leave, axis=1))
        over = np.where(floored, along_floor, over)
    return float(np.maximum(over - np.linalg.norm(chord, axis=1), 0.0).sum())


def stated_shortfall(shortfall_mm: float, girth_mm: float) -> float | None:
    """A girth's uncertainty as the record states it (mm): what its loop may miss when
    more than an order's GIRTH_TOLERANCE_MM, at most the girth itself (a loop whose gap
    has no bound, :func:`chord_excess`'s inf); None within the tolerance."""
    return float(min(shortfall_mm, girth_mm)) if shortfall_mm > GIRTH_TOLERANCE_MM else None


def loop_girth(section: np.ndarray, floor: tuple[np.ndarray, float], chord_sag: float) -> tuple[float, float]:
    """The tape girth (mm) of a closed section's points (n, 2): the convex hull of the
    points moved onto the smooth curve they sample
    (:func:`app.geometry.sections.project_on_local_quadratics`: a scanner's noise averaged
    across the curve, a clean section's points left on it), and how much longer the skin
    may be than that hull (mm: :func:`chord_excess` over the ``floor`` (gradient, level),
    and the crossings' depth, ``chord_sag`` mm^2 times the loop's mean curvature).  (The calf's polar fit,
    :func:`app.geometry.sections.tape_girths`, is built for round sections: its few
    harmonics cut the corners of a foot's long oblique loops by up to 15%.)"""
    loop = project_on_local_quadratics(section)
    girth = float(ConvexHull(loop).area)
    # crossings inside the skin by chord_sag times its curvature, on average 2 pi / girth
    # round a closed convex loop: the tape shorter by 2 pi times their mean depth
    return girth, chord_excess(loop, *floor) + 4.0 * np.pi**2 * chord_sag / girth


def extreme_tape(sections: list[np.ndarray], coarse: np.ndarray, planes: int, largest: bool,
                 floors: list[tuple[np.ndarray, float]], chord_sags: np.ndarray) -> tuple[int, float, float]:
    """The tape band at the largest (or least) girth among the planes' ``sections`` (k
    lists of (n, 2) points, in order), some closed: the band of ``planes`` (odd) neighbours
    whose median ``coarse`` girth (k,) mm (:func:`hull_girths`, NaN where not closed) is
    largest (least), then its tape (:func:`loop_girth`, median over the band's closed
    sections) and how much longer the skin may be (the median of their shortfalls,
    :func:`loop_girth`: ``floors``, each plane's floor for :func:`chord_excess`,
    ``chord_sags`` (k,) its crossings' sags, :func:`loop_sections`).  The moving least squares costs
    ~1 ms a section, the hull ~0.05: read on the band alone, the foot's 40 sections cost
    the fit ~15 ms, not ~170; near the extreme the girth changes to second order, so the
    plane the raw hulls rank first reads within a fraction of a millimetre of the one the
    tapes would.  (index, mm, mm)."""
    band = np.where(np.isfinite(coarse), running_median(coarse, planes), np.nan)
    best = int(np.nanargmax(band) if largest else np.nanargmin(band))
    near = range(max(best - planes // 2, 0), min(best + planes // 2 + 1, len(sections)))
    read = np.array([loop_girth(sections[i], floors[i], chord_sags[i]) for i in near if np.isfinite(coarse[i])])
    return best, float(np.median(read[:, 0])), float(np.median(read[:, 1]))
