"""A point cloud too sparse for thin slabs (a body mesh's vertices, a registered
template's): how dense it is, the neighbour graph its tape girths are read on, and its
refusal when its sections cannot be closed at all.  Units: mm.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from app.geometry.anatomy.calf_candidates import KNEE_ABOVE_CALF_MM
from app.geometry.anatomy.feature_layers import b1_height
from app.geometry.anatomy.landmarks import smooth_profile
from app.geometry.anatomy.waists import TAPE_RESOLUTION_MM, WAIST_FIT_MM, WAIST_MIN_FLANK_MM, waist_vertex
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.sections import LimbGraph, PolarSections, graph_sections, limb_graph, neighbour_edges, tape_girths
from app.geometry.sections.cloud import MIN_CLOUD_POINTS_PER_MM

#: a cloud whose sections cannot be closed (fewer than 90% of them, after bridging the
#: open ones from their neighbours) and whose slabs hold a point in fewer than this share
#: of the 5-degree sectors around the leg (median) is too sparse rather than not a leg;
#: refused as too_sparse with the density found and needed (MIN_CLOUD_POINTS_PER_MM)
MIN_SECTOR_COVERAGE = 0.6
#: below this density (the slabs are then thicker than 8 mm), a cloud's girths are
#: warned about: a thick slab at the ankle minimum reads the wider leg above and below
SPARSE_CLOUD_POINTS_PER_MM = 18.0


def calf_density(local: np.ndarray, d_mm: float) -> float:
    """A cloud's points per mm of the calf's height, B (z = 0) to D; local (n, 3) calf-frame mm."""
    return int(np.count_nonzero((local[:, 2] >= 0.0) & (local[:, 2] <= d_mm))) / max(d_mm, 1e-9)


def sparse_cloud_graph(local: np.ndarray, faces: np.ndarray | None, d_mm: float) -> LimbGraph | None:
    """A sparse cloud's neighbour graph (a LimbGraph), its tape girths read on it; None for a
    mesh or a cloud dense enough for thin slabs.

    Below :data:`SPARSE_CLOUD_POINTS_PER_MM` a slab must be 8-20 mm thick to close a
    section: a tessellation's rings of vertices, tilted to the plane, fall into it as arcs
    from different heights, and a bin's one or two points leave the fit to guess between
    them (on the knee's and thigh's slopes, 1-3 mm of radius per cm of height).  The
    edges of the mutual nearest-neighbour graph cross the tape's plane exactly in it, as
    a mesh's triangles do, and each crossing is put round the section's centre, on the
    skin rather than on the chord (:func:`app.geometry.sections.cloud_edges.round_edge_crossings`).
    Measured (``benchmarks/chart_accuracy.py 8 11``, the body_vertices and
    sparse_leg_vertices re-scans against the clean mesh, |error| p95 in mm, slabs ->
    graph): cB1 4.0-4.6 -> 3.0-3.1, cC 0.7-0.8 -> 0.3-0.4, cD 1.8 -> 0.6-1.4, cG 3.4 ->
    3.0, cB 0.6-0.7 -> 1.1 (the malleoli's flats, read round).  A dense cloud keeps its
    thin slabs, which average a scanner's noise over more points than a plane's
    crossings hold.

    The graph (:func:`app.geometry.sections.limb_graph.limb_graph`) is the mutual one,
    no point taken for a scanner's streak (``drop_streaks=False``), with each point
    joined also to its nearest above and below along the leg, whose crossings follow the
    skin's bend along it.  A body mesh's rings lie up to four times farther apart than
    their points: the mutual graph joined none of them to the next and took half of their
    arcs for streaks, and the planes between them were open over B1's whole rise
    (chart_accuracy 8 11, legs 1 and 5: cB1 2.1-3.5 mm short, read on the slabs), and
    at the ankle the mutual graph's sections closed with 45-55 degree arcs empty, which
    the polar fit bridged short.  Measured on the body_vertices and sparse_leg_vertices
    re-scans of chart_accuracy 8 3, 5, 7, 9, 11 and 13 (85 scans against the clean
    mesh, |error| p95 in mm, the mutual graph -> this one): cB 1.54-1.65 -> 0.38-0.46,
    cB1 1.68-2.70 -> 0.45-0.48, lB1 3.55-4.36 -> 0.28-0.31, cC 0.43-0.55 -> 0.45-0.54
    (read on chords instead of the bend: 0.43-0.84, up to 2.2 mm short at the bulge),
    cF 1.09-1.40 -> 1.33-1.77 (stated uncertain on these scans), cG 1.08-1.49 ->
    1.19-1.26, lG 1.84-3.94 -> 2.73-4.10.  A cloud this sparse is a tessellation's
    vertices, which have no streaks (a scanner's raw cloud holds 10 to 100 times more
    points); strays apart from the skin are still dropped with their small components.
    The gluteal fold is read on the mutual graph with its streak test, as before.
    local (n, 3) calf-frame mm, B at z = 0; ``d_mm`` D's height."""
    if faces is not None or calf_density(local, d_mm) >= SPARSE_CLOUD_POINTS_PER_MM:
        return None
    tree = cKDTree(local)
    return limb_graph(local, neighbour_edges(local, tree=tree, drop_streaks=False), neighbour_edges(local, tree=tree))


#: the knee waist read again on the graph: its girth every WAIST_STEP_MM over this far
#: either side of the slabs' D, mm
WAIST_REACH_MM = 2 * WAIST_FIT_MM
WAIST_STEP_MM = 2.0
#: B1 is read on the graph only where the graph closes a section this near it below and
#: above, mm (b1_on_graph)
B1_GRAPH_REACH_MM = 6.0


def knee_waist_on_graph(local: np.ndarray, graph: LimbGraph, d_mm: float, at_scan_edge: bool,
                        c_mm: float | None = None) -> tuple[float, bool]:
    """D's height (mm) read again on a sparse cloud's neighbour graph, and whether it is
    still at the scan's edge.  The waist's vertex (:func:`app.geometry.anatomy.waists.waist_vertex`,
    the rule the placement reads it by) of the graph's tape girths every WAIST_STEP_MM
    within WAIST_REACH_MM of the slabs' ``d_mm``, round the lowest of them within
    WAIST_FIT_MM of it; ``d_mm`` itself where the graph closes too few of those sections.
    D moves only to a vertex the graph reads inside the scan: WAIST_MIN_FLANK_MM under
    its last closed section, whose girth is TAPE_RESOLUTION_MM more (a waist reached, as
    :func:`app.geometry.anatomy.waists.minimum_reached_at_edge` asks of the edge); else
    it stays where the slabs took it, at the scan's edge when ``at_scan_edge``.  (Within
    a vertex spacing of a cut the graph's sections lose the edges across the cut and read
    short: a sparse lower leg's D moved from the slabs' 357 mm to 377, 8 mm under the
    cut, where the graph read the girth 6 mm less than at the waist - lD 23.6 mm off the
    clean mesh's, unwarned: benchmarks/chart_accuracy.py 8 3, leg 0.)

    The placement reads the profile on slabs up to 20 mm thick, whose girths scatter by
    3-8 mm on a body mesh's vertices: the vertex of a flat knee waist moved with that
    scatter, D 6-12 mm off the clean mesh's (benchmarks/chart_accuracy.py 8 11:
    body_vertices and sparse_leg_vertices, legs 3 and 4); the graph reads a plane's girth
    within 0.7 mm p95 (:func:`sparse_cloud_graph`) and put those D within 1.2 mm of the
    clean mesh's.

    Given C's height ``c_mm``, D also moves down to a waist the graph reads below that
    window (:func:`_waist_below_window`): the slabs can put D on the knee's rise, more
    than WAIST_FIT_MM above a flat waist, where the window never sees it.  local (n, 3)
    calf-frame mm, B at z = 0; graph its LimbGraph."""
    if c_mm is not None:
        below = _waist_below_window(local, graph, c_mm, d_mm)
        if below is not None:
            return below, False
    top = float(local[:, 2].max())
    heights = np.arange(d_mm - WAIST_REACH_MM, min(d_mm + WAIST_REACH_MM, top - WAIST_STEP_MM), WAIST_STEP_MM)
    girth = tape_girths(local, None, heights, graph)
    measured = np.isfinite(girth)
    near = np.flatnonzero((np.abs(heights - d_mm) <= WAIST_FIT_MM) & measured)
    if measured.sum() < 10 or not len(near):
        return d_mm, at_scan_edge
    lowest = int(near[np.argmin(smooth_profile(heights, girth)[near])])
    vertex = waist_vertex(heights, girth, lowest, float(heights[0]), float(heights[-1]))
    last = int(np.flatnonzero(measured)[-1])
    inside = (heights[last] - vertex >= WAIST_MIN_FLANK_MM
              and girth[last] - np.interp(vertex, heights[measured], girth[measured]) >= TAPE_RESOLUTION_MM)
    return (vertex, False) if inside else (d_mm, at_scan_edge)


def _waist_below_window(local: np.ndarray, graph: LimbGraph, c_mm: float, d_mm: float) -> float | None:
    """The knee waist's height (mm) where the graph reads it below the window
    :func:`knee_waist_on_graph` searches (more than WAIST_FIT_MM under the slabs'
    ``d_mm``), or None where it reads none there.

    The rule is the placement's for D (app.geometry.anatomy.calf_candidates): the knee
    waist is the least girth from KNEE_ABOVE_CALF_MM[0] above C up.  The graph's girths
    every WAIST_STEP_MM from there to WAIST_FIT_MM above ``d_mm``, smoothed as the
    placement smooths a profile (:func:`app.geometry.anatomy.landmarks.smooth_profile`):
    D moves only when their least value below the window is at least TAPE_RESOLUTION_MM
    under the least within it (a tape reads to 1 mm at each end: less is no thinner
    waist), and only to a local minimum with WAIST_MIN_FLANK_MM of profile below it (not
    the range's lower end, where the calf is still narrowing) - the vertex of the
    parabola round it (:func:`app.geometry.anatomy.waists.waist_vertex`).  Only down:
    near the scan's cut above, a graph's sections lose the edges across the cut and
    read short (see :func:`knee_waist_on_graph`).

    Why: on the Visible Human male's right leg read as 5,000 of its vertices, the slabs
    put D 43 mm above a flat knee waist, on the knee's rise; the graph read the waist
    (394 mm at 300-304 mm) 24 mm under the window's bottom, and D stayed 22.5 mm high
    with cD 10 mm long, its height tolerance stated as 6.6 mm.  local (n, 3) calf-frame
    mm; graph its LimbGraph."""
    window_low = d_mm - WAIST_FIT_MM
    low = c_mm + KNEE_ABOVE_CALF_MM[0]
    if window_low - low < WAIST_MIN_FLANK_MM + WAIST_STEP_MM:
        return None
    top = float(local[:, 2].max())
    heights = np.arange(low, min(d_mm + WAIST_FIT_MM, top - WAIST_STEP_MM), WAIST_STEP_MM)
    girth = tape_girths(local, None, heights, graph)
    measured = np.isfinite(girth)
    within = (heights >= window_low) & measured
    under = (heights < window_low) & (heights - low >= WAIST_MIN_FLANK_MM) & measured
    if measured.sum() < 10 or not within.any() or not under.any():
        return None
    smooth = smooth_profile(heights, girth)
    lowest = int(np.flatnonzero(under)[np.argmin(smooth[under])])
    if smooth[lowest] > smooth[within].min() - TAPE_RESOLUTION_MM or smooth[lowest] > smooth[lowest - 1]:
        return None
    return waist_vertex(heights, girth, lowest, float(heights[0]), float(heights[-1]))


def b1_on_graph(local: np.ndarray, graph: LimbGraph, b_mm: float, c_mm: float) -> float | None:
    """B1's height (mm) on a sparse cloud's neighbour graph: halfway up the rise of its
    tape girths from B to C (:func:`app.geometry.anatomy.feature_layers.b1_height`), read
    every WAIST_STEP_MM on the graph rather than on the fit's slabs, whose girths scatter
    by 3-8 mm on a body mesh's vertices (:func:`knee_waist_on_graph`); None where the
    graph closes fewer than 10 of those sections or none within B1_GRAPH_REACH_MM below
    or above its B1 (a body mesh's coarse stretch of the calf left the graph open over
    120 mm, and B1 read on the straight line bridging it lay 4.4 mm low, cB1 7.6 mm
    short: benchmarks/robustness.py 220 7, body_vertices-04).  B1 lies on the calf's
    steepest rise, 1-1.5 mm of girth per mm of height: where its height goes, cB1
    follows.  local (n, 3) calf-frame mm, B at z = 0; graph its LimbGraph."""
    rise = np.arange(b_mm, c_mm + WAIST_STEP_MM, WAIST_STEP_MM)
    girth = tape_girths(local, None, rise, graph)
    measured = rise[np.isfinite(girth)]
    if len(measured) < 10:
        return None
    b1_mm = b1_height(rise, girth, b_mm, c_mm)
    below, above = measured[measured <= b1_mm], measured[measured >= b1_mm]
    if not (len(below) and len(above)):
        return None
    return b1_mm if max(b1_mm - below[-1], above[0] - b1_mm) <= B1_GRAPH_REACH_MM else None


def open_sections_on_graph(local: np.ndarray, graph: LimbGraph, sections: PolarSections) -> PolarSections:
    """A sparse cloud's ``sections`` (the calf's, or its feature layers: PolarSections at
    ascending heights on a ray grid) with each one its slab left open read where the
    neighbour ``graph``'s edges cross its plane (:func:`app.geometry.sections.graph_sections`),
    the rest as they are.  The fit calls it only where the slabs and their bridging
    (app.geometry.sections.polar.bridge_sections) leave the cloud too sparse to fit -
    fewer than 90% of the calf's sections closed, or a feature layer open - so every
    cloud fitted before is fitted as before, on its slabs.

    A coarse body mesh's vertices leave a stretch of its skin without a point for 20 mm
    and more along the leg where its triangles are long: on two knee-high sparse clouds
    (5.5k vertices, 2.5 per mm of the calf) every 20 mm slab within 12 mm of C missed a
    120-degree arc round the back of the calf, and the fit refused them as too sparse
    (benchmarks/robustness.py 220 17 and 19, sparse_leg_vertices-00 and -01; a third,
    chart_accuracy.py 8 17 leg 5, at its calf's sections, 82% closed).  The graph's
    edges along the limb join the points above and below such a stretch and close the
    planes across it.

    Not on a cloud sparser than MIN_CLOUD_POINTS_PER_MM (1 per mm of the leg): a random
    3,000 of the Visible Human male's vertices (0.6 per mm) fitted so put C 33-48 mm and D
    36-65 mm below the mesh's and cD 11-14 mm long, warned only as sparse
    (tests/geometry/test_fit_real.py, refused too_sparse before and again now): where the
    points are that few, the placement's B, C and D are not to be trusted either, and the
    slabs' refusal is the safeguard.  local (n, 3) calf-frame mm."""
    open_rows = np.flatnonzero(~sections.valid)
    on_graph = graph_sections(local, graph, sections.heights_mm[open_rows], len(sections.angles_rad))
    return sections.with_rows(open_rows, on_graph)


def too_sparse(what: str, covered: float, density: float, closed: float) -> FitFailure:
    """The refusal of a cloud too sparse to close ``what`` (module constants above)."""
    return FitFailure(
        FailureReason.TOO_SPARSE,
        f"the cloud is too sparse to close {what}: it has {density:.1f} points per mm of the calf's height and its "
        f"slabs (up to 20 mm thick) hold points in {covered:.0%} of the 5-degree sectors around the leg (median), so "
        f"{closed:.0%} of the sections could be closed (90% are needed); a cloud needs about "
        f"{MIN_CLOUD_POINTS_PER_MM:g} point per mm of the leg's height, {MIN_CLOUD_POINTS_PER_MM * 20:.0f} in each "
        "slab, spread round the leg: export the scan denser, or as a mesh")
