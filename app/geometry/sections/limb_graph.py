"""A sparse cloud's graph on a limb: the skin's mutual-neighbour edges
(:func:`app.geometry.sections.cloud_edges.neighbour_edges`) and edges along the limb,
each point to its nearest above and below, whose plane crossings follow the skin's bend
along the limb (a cubic Hermite curve, Catmull-Rom's tangents) rather than the chord.

Why edges along the limb.  A tessellation's vertices lie in rings round a limb, and
where its rings lie farther apart than a point's NEIGHBOURS nearest reach within its
ring, the mutual graph joins no ring to the next: a plane between two rings crosses no
edge and its section is open, or open over a wide arc that the polar fit bridges short.
A body mesh's lower calf has rings 28 mm apart with points 7 mm apart round them
(benchmarks/chart_accuracy.py 8 11, leg 5, body_vertices: the graph open from 66 to 146
mm above B, over the whole of B1's rise); at the ankle its sections closed with arcs of
45-55 degrees empty and read cB 1-3.5 mm short (seeds 3-13, 44 of the 85 fitted sparse re-scans
more than 0.5 mm short).  The skin between two rings runs from one to the other as the
mesh's faces did, so a point's nearest above and below "along the limb" - within
:data:`ALONG_LIMB_CONE_DEG` of its axis - are its neighbours on the skin there: within
45 degrees they lie on its side of the limb; the far side is a limb's diameter (60-180
mm) away across it, more than the rings' spacing.

Why not the chord.  An edge along the limb spans a ring's gap, and the skin bends over
it: at the calf's bulge the girth falls ~10 mm 40 mm either side of C, and a chord over a
28 mm gap lies 0.2 mm of radius inside the skin - read linearly, cC came out 1.3-2.2 mm
short on three body-vertex re-scans (seeds 3, 11, 13).  Each edge's crossing is moved
by the bend of the cubic Hermite curve through its ends, with the tangents of the chain
one point further either way (the lower end's nearest below, the upper end's nearest
above: Catmull-Rom's, parametrised by height; Catmull and Rom 1974, de Boor's "A
Practical Guide to Splines" ch. IV on cubic Hermite interpolation), added to the
crossing interpolated round the section's centre
(:func:`app.geometry.sections.cloud_edges.round_about_centres`), which takes the bend
round the limb.  Where the chain ends the tangent is the chord's and the crossing stays
linear along the limb.

Units: mm.  Arrays: points (n, 3) in a frame whose z runs along the limb.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from app.geometry.sections.cloud_edges import crossing_ends, round_about_centres

#: a point's nearest neighbour above (and below) along the limb: within this angle of
#: the limb's axis, among its ALONG_LIMB_CANDIDATES nearest (a ring of 40 points and the
#: rings either side of it: the next ring's point above is among them)
ALONG_LIMB_CONE_DEG = 45.0
ALONG_LIMB_CANDIDATES = 40


@dataclass(frozen=True)
class LimbGraph:
    """A sparse cloud's edges on a limb (module docstring).

    skin : (e, 2) int
        The mutual graph's edges round the limb (more than ALONG_LIMB_CONE_DEG off its
        axis), lower index first.
    along : (a, 2) int
        The edges along the limb - each point to its nearest above and below, and the
        mutual graph's within ALONG_LIMB_CONE_DEG of the axis - the lower point (in z)
        first.
    beyond : (a, 2) int
        Each edge's chain one point further: the lower end's nearest below and the
        upper end's nearest above along the limb, -1 where there is none.
    mutual : (m, 2) int
        The mutual graph as :func:`app.geometry.sections.cloud_edges.neighbour_edges`
        gives it, streaks dropped: the back's profile the gluteal fold is found on
        (app.geometry.anatomy.gluteal_fold.posterior_profile) is read on it alone.
    """

    skin: np.ndarray
    along: np.ndarray
    beyond: np.ndarray
    mutual: np.ndarray

    @cached_property
    def edges(self) -> np.ndarray:
        """(e + a, 2): every edge, the skin's first (joined once per graph: every tape
        read on it crosses them all)."""
        return np.concatenate([self.skin, self.along])

    def renumbered(self, new_index: np.ndarray) -> LimbGraph:
        """The same graph over the points reordered so that point i is ``new_index[i]``."""
        beyond = np.where(self.beyond >= 0, new_index[np.maximum(self.beyond, 0)], -1)
        return LimbGraph(new_index[self.skin], new_index[self.along], beyond, new_index[self.mutual])


def _along_the_limb(offset: np.ndarray) -> np.ndarray:
    """(...,) bool: the offsets (..., 3) within ALONG_LIMB_CONE_DEG of the z axis, up or down."""
    return np.abs(offset[..., 2]) >= np.cos(np.radians(ALONG_LIMB_CONE_DEG)) * np.linalg.norm(offset, axis=-1)


def limb_graph(points: np.ndarray, skin_edges: np.ndarray, mutual: np.ndarray | None = None) -> LimbGraph:
    """The :class:`LimbGraph` of ``points`` (n, 3) whose skin is ``skin_edges`` (e, 2)
    (and whose ``mutual`` graph is given, else ``skin_edges``):
    each skin point (an end of one of them) joined to its nearest skin point above and
    its nearest below along the limb, each such pair once; the mutual graph's own edges
    within the cone are read along the limb too (on its bend), the rest round it."""
    mutual = skin_edges if mutual is None else mutual
    skin = np.unique(skin_edges)
    if len(skin) < 2:
        empty = np.empty((0, 2), dtype=np.int64)
        return LimbGraph(skin_edges, empty, empty, mutual)
    local = points[skin]
    k = min(ALONG_LIMB_CANDIDATES, len(skin) - 1)
    _, nearest = cKDTree(local).query(local, k=k + 1)
    nearest = nearest[:, 1:]  # (s, k) rising distance, each point itself left out
    offset = local[nearest] - local[:, None, :]  # (s, k, 3)
    cone = _along_the_limb(offset)
    up, down = np.full(len(points), -1), np.full(len(points), -1)  # each point's nearest above / below
    for neighbour, inside in ((up, cone & (offset[..., 2] > 0)), (down, cone & (offset[..., 2] < 0))):
        found = inside.any(axis=1)
        neighbour[skin[found]] = skin[nearest[found, np.argmax(inside, axis=1)[found]]]
    # the mutual graph's own edges within the cone run along the limb too
    run = points[skin_edges[:, 1]] - points[skin_edges[:, 0]]
    in_cone = _along_the_limb(run)
    rising = run[:, 2] > 0
    joined, joined_below = up[skin] >= 0, down[skin] >= 0
    pairs = np.concatenate([np.column_stack([skin[joined], up[skin[joined]]]),
                            np.column_stack([down[skin[joined_below]], skin[joined_below]]),
                            np.where(rising[:, None], skin_edges, skin_edges[:, ::-1])[in_cone]])
    along = np.unique(pairs, axis=0)  # (lower, upper) in z, each pair once
    return LimbGraph(skin_edges[~in_cone], along, np.column_stack([down[along[:, 0]], up[along[:, 1]]]), mutual)


def limb_crossings(points: np.ndarray, graph: LimbGraph, heights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where ``graph``'s edges cross the planes ``z = heights`` (k,, ascending): every
    crossing round its plane's centre, an edge along the limb's moved by the skin's bend
    along it (module docstring).  Returns plane (s,) int and the crossings' (x, y) (s, 2), mm."""
    plane, edge, a, b, t = crossing_ends(points, graph.edges, heights)
    crossings = round_about_centres(plane, a, b, t, len(heights))
    along = np.flatnonzero(edge >= len(graph.skin))
    if len(along):
        crossings[along] += along_limb_bend(points, graph, edge[along] - len(graph.skin), t[along])
    return plane, crossings


def along_limb_bend(points: np.ndarray, graph: LimbGraph, edge: np.ndarray, t: np.ndarray) -> np.ndarray:
    """(s, 2) mm: the cubic Hermite curve's offset from the chord of the edges along the
    limb ``edge`` (s,) (indices into ``graph.along``) at ``t`` (s,) of the way up each,
    in x and y.  Catmull-Rom tangents by height: at the lower end p, (q - o) (z_q - z_p) /
    (z_q - z_o), o the point below p; at the upper end q, (u - p) (z_q - z_p) / (z_u - z_p),
    u the point above q; the chord's own where o or u is missing (no bend from that end).

    The Hermite curve minus the chord, with h10 = t^3 - 2t^2 + t and h11 = t^3 - t^2:
    h10 m_p + h11 m_q - (h10 + h11) (q - p)."""
    p, q = points[graph.along[edge, 0]], points[graph.along[edge, 1]]
    o_index, u_index = graph.beyond[edge, 0], graph.beyond[edge, 1]
    chord = q - p
    o, u = points[np.maximum(o_index, 0)], points[np.maximum(u_index, 0)]
    with np.errstate(divide="ignore", invalid="ignore"):
        m_p = np.where((o_index >= 0)[:, None], (q - o) * (chord[:, 2] / (q[:, 2] - o[:, 2]))[:, None], chord)
        m_q = np.where((u_index >= 0)[:, None], (u - p) * (chord[:, 2] / (u[:, 2] - p[:, 2]))[:, None], chord)
    h10, h11 = t**3 - 2 * t**2 + t, t**3 - t**2
    bend = h10[:, None] * m_p + h11[:, None] * m_q - (h10 + h11)[:, None] * chord
    return bend[:, :2]
