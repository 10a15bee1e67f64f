"""A point cloud's plane sections read on its neighbour graph: where the edges joining
points that are each other's nearest neighbours cross the plane, linearly interpolated.

A cloud has no triangles, and a plane holds none of its points.  A slab of points within
a half thickness of the plane, projected onto it, reads a loop as the hull of every
section the slab spans: on a sparse or uneven cloud (a body mesh's vertices, 0.4-11 mm
apart on one foot) the slab must be as thick as the widest spacing to close the loop, and
where the plane cuts the skin at a slant - the heel, the instep - the loop grows by the
skin's run across the slab (cY read up to 15 mm long on such clouds, and the ball girth
cA up to 4 mm short where the slab's few points left whole bins empty).

The graph stands in for the mesh the scanner did not send: on a surface sampled finer
than its thickness and its curvature radius, a point's nearest neighbours are its
neighbours on the skin, and an edge between two of them is a chord of the skin.  A plane
crossing an edge crosses the skin between its ends: the crossing, interpolated linearly
along the edge, lies on the chord - within the chord's sagitta (length^2 / 8R: 0.3 mm for
a 9 mm edge on the heel's ~30 mm radius) of the skin - and exactly in the plane.  This is
the section a mesh gives (:func:`app.geometry.sections.mesh.mesh_section_segments`
crosses a triangle's two edges the same way), with neighbour pairs for the triangles.
Edges across the inside of the limb need a point's :data:`NEIGHBOURS` nearest to lie
across its thickness: the foot is 20 mm thick at the toes and 40-60 at the ball, more
than the neighbours' reach on any scan the fit takes (a cloud needs 1 point per mm of
the leg's height, app.geometry.sections.cloud.MIN_CLOUD_POINTS_PER_MM).

A scanner's stray points are no skin, and every edge among them would cross a plane as
the skin's do (a line of floor points beside the forefoot, crossed by a dozen edges,
outvoted the skin in its angle bin and read cA up to 32 mm long).  Three rules keep them out:

- only *mutual* neighbours are joined (each among the other's :data:`NEIGHBOURS`
  nearest): a point off the skin has skin points among its nearest, but they have
  nearer skin of their own, so it is joined to nothing (the mutual k-nearest-neighbour
  graph: Maier, Hein and von Luxburg, "Optimal construction of k-nearest-neighbor graphs
  for identifying noisy clusters", Theoretical Computer Science 410, 2009);
- the skin is a surface: a point whose nearest spread along one line is on a scanner's
  streak (:func:`on_a_streak`, the rule app.geometry.anatomy.sole's skin test uses) and
  joined to nothing - a streak leaves the skin from a root on it, so its own edges,
  crossing a plane all at one point a dozen times, would join the skin's component (a
  streak beside the forefoot read cA 8 mm long, chart_accuracy 8 5);
- the skin is one connected surface: only the graph's components holding at least
  :data:`MIN_SKIN_SHARE` of the points are kept, so a clump of ghosts or a sheet of
  floor points, joined among themselves, is dropped whole.

On a limb's round sections (a sparse cloud's tape girths, app.geometry.fit.sparse_clouds.
sparse_cloud_graph) a crossing is interpolated in radius and angle about the plane's
centre instead (:func:`round_edge_crossings`): the chord of a coarse tessellation's edge
lies a sagitta inside the skin, which its vertices lie on.

Units: mm.  Arrays: points (n, 3) in the frame whose z the heights are, edges (e, 2).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse import triu as sparse_triu
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from app.geometry.sections.polar import plane_pairs

#: a point's neighbours are its this-many nearest.  On a tessellation's vertices a point
#: has ~6 neighbours on the skin; 10 leaves no loop open where the tessellation is
#: stretched (6 read cY up to 0.9 mm off the mesh's on 13 sparse vertex clouds, 10 within
#: 0.8 mm)
NEIGHBOURS = 10
#: a scanner's streak (a line of points leaving the skin, 30-80 mm long): the second
#: largest spread (eigenvalue of the covariance) of a point's STREAK_NEIGHBOURS nearest
#: under STREAK_SHARE of the largest.  On skin they spread over a patch of the surface
#: (a share of 0.1 or more even on a tessellation's rings, 3 times as far apart as their
#: points); on a streak along it, the second spread the streak's own scatter
STREAK_NEIGHBOURS = 8
STREAK_SHARE = 0.05
#: the skin is the graph's components holding at least this share of the points (on 80
#: generated foot clouds of 10 kinds, seed 21, the skin was one component of 98.9-100% of
#: them; a scanner's strays - ghosts, floor points, streaks - components of 1-31 points)
MIN_SKIN_SHARE = 0.05


def on_a_streak(points: np.ndarray, nearest: np.ndarray) -> np.ndarray:
    """(k,) bool: the points whose :data:`STREAK_NEIGHBOURS` nearest spread along one line
    (:data:`STREAK_SHARE`), a streak's and not the skin's.  ``nearest`` (k, m >=
    STREAK_NEIGHBOURS + 1): each point's nearest among ``points`` (n, 3), itself first."""
    around = points[nearest[:, : STREAK_NEIGHBOURS + 1]]
    around = around - around.mean(axis=1, keepdims=True)  # (k, m, 3)
    spread = np.linalg.eigvalsh(np.einsum("kmi,kmj->kij", around, around))  # (k, 3) rising
    return spread[:, 1] < STREAK_SHARE * spread[:, 2]


def neighbour_edges(points: np.ndarray, neighbours: int = NEIGHBOURS, tree: cKDTree | None = None,
                    drop_streaks: bool = True) -> np.ndarray:
    """(e, 2) int, lower index first: the skin's edges among ``points`` (n, 3) - the pairs
    each among the other's ``neighbours`` nearest (the mutual k-nearest-neighbour graph),
    neither on a streak (:func:`on_a_streak`; unless ``drop_streaks`` is False), in the
    graph's components of at least :data:`MIN_SKIN_SHARE` of the points (module
    docstring); empty for fewer than two points.  ``tree``: a k-d tree over ``points``
    already built (a caller asking more of the same points shares it).

    A coarse tessellation's vertices are no scanner's and have no streaks, but its rings
    can pass for them: where rings lie four times farther apart than their points (a
    body mesh's lower calf, 28 mm and 7 mm), a point's STREAK_NEIGHBOURS nearest lie on
    its own ring's arc, spread along it 0.03 as much across (an arc of +-28 mm on a 45 mm
    radius), and half of such a ring was dropped as streaks (chart_accuracy 8 11, leg 5,
    body_vertices): a sparse cloud's limb graph is built with ``drop_streaks=False``
    (app.geometry.fit.sparse_clouds.sparse_cloud_graph)."""
    n = len(points)
    k = min(neighbours, n - 1)
    if k < 1:
        return np.empty((0, 2), dtype=np.int64)
    _, nearest = (tree if tree is not None else cKDTree(points)).query(points, k=max(k, STREAK_NEIGHBOURS) + 1)
    skin = ~on_a_streak(points, nearest) if drop_streaks and n > STREAK_NEIGHBOURS else np.ones(n, dtype=bool)
    near, far = np.repeat(np.arange(n), k), nearest[:, 1 : k + 1].ravel()  # a point is its own nearest
    off_streaks = skin[near] & skin[far]
    near, far = near[off_streaks], far[off_streaks]
    chosen = coo_matrix((np.ones(len(near)), (near, far)), shape=(n, n)).tocsr()
    mutual = sparse_triu(chosen.multiply(chosen.T), k=1).tocoo()  # each pair once, as (lower, higher)
    _, component = connected_components(mutual, directed=False)
    size = np.bincount(component)
    kept = size[component[mutual.row]] >= MIN_SKIN_SHARE * n
    return np.column_stack([mutual.row[kept], mutual.col[kept]]).astype(np.int64)


def crossing_ends(points: np.ndarray, edges: np.ndarray, heights: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The plane (s,) of each crossing of an edge with ``z = heights`` (k,, ascending),
    the edge crossing it (s,), its ends (s, 3) each and how far from the first to the
    second the plane lies, t (s,)."""
    z = points[:, 2]
    level = np.searchsorted(heights, z, side="right")
    first, second = level[edges[:, 0]], level[edges[:, 1]]
    crossing = np.flatnonzero(first != second)
    lo, hi = np.minimum(first, second)[crossing], np.maximum(first, second)[crossing]
    pair_edge, plane = plane_pairs(lo.astype(np.int64), hi.astype(np.int64))
    edge = crossing[pair_edge]
    a, b = points[edges[edge, 0]], points[edges[edge, 1]]
    return plane, edge, a, b, (heights[plane] - a[:, 2]) / (b[:, 2] - a[:, 2])


def edge_crossings(points: np.ndarray, edges: np.ndarray, heights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the edges (e, 2) of ``points`` (n, 3) cross the planes ``z = heights`` (k,),
    ascending: an edge crosses a plane when ``z_min < h <= z_max``, at the point linear
    along it.  Returns plane (s,) int and the crossings' (x, y) (s, 2), mm."""
    plane, _, a, b, t = crossing_ends(points, edges, heights)
    return plane, a[:, :2] + t[:, None] * (b[:, :2] - a[:, :2])


def round_edge_crossings(points: np.ndarray, edges: np.ndarray, heights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`edge_crossings` on a limb's round sections: each crossing interpolated in
    radius and angle about its plane's centre (the mean of the plane's linear crossings)
    instead of along the chord.  A limb's skin between two neighbouring points runs round
    the section's centre, not straight: the chord lies inside it by its sagitta, e^2/8R
    (1 mm for a 17 mm edge on a 35 mm ankle: a tape girth 6 mm short), while the arc
    about the centre is the skin's own on a round section.  Same returns, mm."""
    plane, _, a, b, t = crossing_ends(points, edges, heights)
    return plane, round_about_centres(plane, a, b, t, len(heights))


def round_about_centres(plane: np.ndarray, a: np.ndarray, b: np.ndarray, t: np.ndarray, k: int) -> np.ndarray:
    """(s, 2) mm: the crossings of :func:`crossing_ends` (plane (s,) of ``k``, ends a and
    b (s, 3), t (s,)) interpolated in radius and angle about their plane's centre
    (:func:`round_edge_crossings`)."""
    linear = a[:, :2] + t[:, None] * (b[:, :2] - a[:, :2])
    count = np.maximum(np.bincount(plane, minlength=k), 1)
    centre = np.column_stack([np.bincount(plane, linear[:, i], minlength=k) for i in (0, 1)]) / count[:, None]
    from_a, from_b = a[:, :2] - centre[plane], b[:, :2] - centre[plane]
    angle_a = np.arctan2(from_a[:, 1], from_a[:, 0])
    turn = np.angle(np.exp(1j * (np.arctan2(from_b[:, 1], from_b[:, 0]) - angle_a)))  # (-pi, pi]
    radius = (1.0 - t) * np.linalg.norm(from_a, axis=1) + t * np.linalg.norm(from_b, axis=1)
    angle = angle_a + t * turn
    return centre[plane] + radius[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
