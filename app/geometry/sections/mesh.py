"""Parallel cross-sections and polar resampling (paper section 2.1, Figure 2).

The scan is given in a frame whose z axis is the slicing direction (the calf frame or a
provisional one).  Every section ``z = h_k`` is turned into radii ``r[k, j]`` measured
from the section's centroid along the ray at angle ``theta_j = 2*pi*j/n_angles``
(paper: 72 angles, 5 degrees).  All work is vectorized over (section, triangle) and
(section, ray) pairs; there is no Python loop over points, triangles or sections
except over the few sections whose contour has holes.

Meshes: every triangle crossing a plane gives one segment (a multi-plane version of
trimesh.intersections.mesh_multiplane); each ray takes the outermost segment it hits,
so inner shells and folds never shorten the skin contour.  Rays that hit nothing (holes
in the mesh) are filled by periodic interpolation in the polar domain between the
nearest hit rays (the paper's "curve fitting in the polar coordinate system"); the
largest run of such rays is kept (``largest_gap_deg``, where it points): the fit makes a
section open by more than MAX_GAP_DEG missing, as a cloud's is, and refuses a leg seen
from one side (app.geometry.placement.coverage).

Point clouds: a robust polar curve fit of each slab of points,
:mod:`app.geometry.sections.cloud`.

Units: millimetres throughout.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from app.geometry.sections.polar import PolarSections, largest_gap, plane_pairs, polygon_centroid, ray_angles

#: a section whose rays hit the contour less often than this is treated as missing
MIN_RAY_COVERAGE = 0.5
#: a ray that hits nothing (a hole in the mesh) between sections whose same ray hits the
#: skin at most this far apart is read between them, linearly in height, before the
#: rays still missing are read round the section (:func:`_fill_polar_gaps`).  Along the
#: leg a ray's radius changes smoothly over centimetres, round the section it does not
#: (the calf's flat back, the shin's crest): on 3 generated legs' clean meshes (36 rays,
#: sections every 2 mm from the heel to 150 mm above D), rays removed in patches 20-60
#: mm tall and 40-100 degrees wide read the sections' girths within 0.15-1.8 mm p95 (max
#: 3.7) filled along the leg, against 1.6-9.6 mm p95 (max 21) filled round the section;
#: at 80 mm tall the two came close for narrow holes (40 degrees: max 4.5 along the leg,
#: 3.3 round it), so taller holes are read round the section as before.  A flat waist
#: read round a hole's chord was thinner in the hole: the knee waist D moved into it
#: (benchmarks/chart_accuracy.py 8 11, leg 5 holes: lD 7.8 mm low)
AXIAL_FILL_SPAN_MM = 60.0


def mesh_section_segments(
    vertices: np.ndarray, faces: np.ndarray, heights: np.ndarray, outer_only: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """Intersect a triangle mesh with the planes ``z = heights`` all at once: the plane
    index (s,) and end points (s, 2, 2) mm of every segment (:func:`_crossings`), with
    ``outer_only`` only those of each section's outer contours (:func:`outer_contours`:
    a wall inside the skin left out).  vertices (n, 3) mm, faces (f, 3), heights (k,)
    ascending."""
    plane, segments, ends = _crossings(vertices, faces, heights)
    if outer_only:
        keep = outer_contours(plane, segments, ends, len(heights))
        plane, segments = plane[keep], segments[keep]
    return plane, segments


def _crossings(
    vertices: np.ndarray, faces: np.ndarray, heights: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Intersect a triangle mesh with the planes ``z = heights`` all at once.

    A plane crosses a triangle when ``z_min < h <= z_max``; the one corner on its own
    side of the plane (the "lone" corner) and the two edges leaving it give the segment.

    Parameters
    ----------
    vertices : (n, 3) float, mm.  faces : (f, 3) int.  heights : (k,) ascending.

    Returns
    -------
    plane : (s,) int
        Plane index of each segment.
    segments : (s, 2, 2) float
        Segment end points (x, y), mm.
    ends : (s, 2) int64
        The mesh edge each end lies on, as min * n + max of its vertex indices (two
        segments of one plane sharing a key meet there).
    """
    x = np.ascontiguousarray(vertices[:, 0])
    y = np.ascontiguousarray(vertices[:, 1])
    z = np.ascontiguousarray(vertices[:, 2])
    # plane index per vertex (first plane above it); planes lo..hi-1 cross a face.  The
    # corners' least and greatest as two elementwise minimum / maximum of the 3 columns:
    # a reduction along a length-3 axis costs 5x as much (200k faces: 21 vs 4 ms a call)
    level = np.searchsorted(heights, z, side="right").astype(np.int32)
    first, second, third = level[faces[:, 0]], level[faces[:, 1]], level[faces[:, 2]]
    lo = np.minimum(np.minimum(first, second), third)
    hi = np.maximum(np.maximum(first, second), third)
    crossing = np.flatnonzero(hi > lo)
    pair_face, plane = plane_pairs(lo[crossing].astype(np.int64), hi[crossing].astype(np.int64))
    if plane.size == 0:
        return plane, np.empty((0, 2, 2)), np.empty((0, 2), dtype=np.int64)
    corners = faces[crossing[pair_face]]  # (s, 3)
    h = heights[plane]
    tz = z[corners]
    above = tz >= h[:, None]
    # exactly one corner is on its own side: the lone one
    lone_mask = above ^ (above.sum(axis=1) == 2)[:, None]
    lone = lone_mask[:, 1].astype(np.int64) + 2 * lone_mask[:, 2]
    base = np.arange(plane.size) * 3
    flat = corners.ravel()
    ia = flat[base + lone]
    ib = flat[base + (lone + 1) % 3]
    ic = flat[base + (lone + 2) % 3]
    za = z[ia]
    tb = (h - za) / (z[ib] - za)
    tc = (h - za) / (z[ic] - za)
    xa, ya = x[ia], y[ia]
    segments = np.empty((plane.size, 2, 2))
    segments[:, 0, 0] = xa + tb * (x[ib] - xa)
    segments[:, 0, 1] = ya + tb * (y[ib] - ya)
    segments[:, 1, 0] = xa + tc * (x[ic] - xa)
    segments[:, 1, 1] = ya + tc * (y[ic] - ya)
    # each end is where the plane crosses a mesh edge: (plane, edge) names it, and the
    # segments sharing ends chain into the section's contours
    n = np.int64(len(vertices))
    ends = np.column_stack([np.minimum(ia, ib) * n + np.maximum(ia, ib), np.minimum(ia, ic) * n + np.maximum(ia, ic)])
    return plane, segments, ends


def inner_contour_share(vertices: np.ndarray, faces: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """(k,) the length of each section's contours that lie inside its outer ones
    (:func:`outer_contours`) over the outer ones' length: about 1 where a wall runs
    inside the whole skin (a hollowed mesh), near 0 for a skin's section, NaN where the
    plane cuts nothing.  vertices (n, 3) mm, faces (f, 3), heights (k,) ascending mm."""
    plane, seg, ends = _crossings(vertices, faces, heights)
    k = len(heights)
    length = np.hypot(*(seg[:, 1] - seg[:, 0]).T)
    every = np.bincount(plane, weights=length, minlength=k)
    keep = outer_contours(plane, seg, ends, k)
    outer = np.bincount(plane[keep], weights=length[keep], minlength=k)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(outer > 0, (every - outer) / outer, np.nan)


#: the rays from a section's centroid a contour must be outermost on to be skin
#: (:func:`outer_contours`; the hole test's 5 degrees)
OUTER_CONTOUR_RAYS = 72


def outer_contours(plane: np.ndarray, seg: np.ndarray, ends: np.ndarray, k: int) -> np.ndarray:
    """(s,) bool: the segments of the contours that are the outermost hit of at least
    one of :data:`OUTER_CONTOUR_RAYS` rays from their section's centroid.

    plane (s,), seg (s, 2, 2) mm as :func:`mesh_section_segments` gives them over k
    planes; ends (s, 2) int: a key per end naming the mesh edge it lies on (two segments
    sharing a key in one plane meet there).  The contours are the connected components
    of the segments joined at shared ends (scipy.sparse.csgraph).  A tape reaches round
    the skin: a contour wholly inside another - the inner wall of a mesh hollowed or
    given a wall for 3D printing, an interior fragment - touches no ray's outermost
    hit and is no part of the skin's section.  The skin's own contour (or, across a
    hole, each of its open pieces) is outermost where it faces out.  Mesh sections
    read their radii on the outermost hits already (:func:`_cast_rays`); this is for
    readings of the segments themselves (a tape's robust polar fit of their ends), where
    an inner wall 3 mm in read every girth 10 mm short.
    """
    if not len(plane):
        return np.zeros(0, dtype=bool)
    # one node per (plane, edge) crossing
    _, node = np.unique(ends * np.int64(k) + plane[:, None], return_inverse=True)
    node = node.reshape(-1, 2)
    graph = csr_matrix((np.ones(len(node)), (node[:, 0], node[:, 1])), shape=(int(node.max()) + 1,) * 2)
    n_contours, contour_of_node = connected_components(graph, directed=False)
    contour = contour_of_node[node[:, 0]]  # (s,)
    plane_of_contour = np.zeros(n_contours, dtype=np.int64)
    plane_of_contour[contour] = plane
    several = np.bincount(plane_of_contour, minlength=k)[plane] > 1  # (s,) in a plane of 2+ contours
    if not several.any():  # one contour a plane (a whole skin's section): nothing inside it
        return np.ones(len(plane), dtype=bool)
    tested = np.flatnonzero(several)
    seg_idx, flat, r = _ray_hits(plane[tested], seg[tested], np.nan_to_num(_segment_centroids(plane, seg, k)),
                                 OUTER_CONTOUR_RAYS)
    order = np.lexsort((r, flat))
    last = np.r_[flat[order][1:] != flat[order][:-1], True]  # the outermost hit of each (plane, ray)
    outer = np.ones(n_contours, dtype=bool)
    outer[contour[tested]] = False
    outer[contour[tested[seg_idx[order][last]]]] = True
    return outer[contour]


def _fill_along_axis(radii: np.ndarray, heights: np.ndarray, origins: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Fill each NaN ray of ``radii`` (k, a) between the nearest sections below and above
    whose same ray hits, where those lie at most :data:`AXIAL_FILL_SPAN_MM` apart; other
    rays as they are.  (k, a) mm.  The rays of each section start at its own ``origins``
    (k, 2) mm (a hole shifts a section's centroid away from it), so the skin point is
    read between the two hits' points, linearly in ``heights`` (k,) ascending mm, and
    the ray's radius is that point's reach along the ray from the section's origin."""
    k, a = radii.shape
    hit = np.isfinite(radii)
    rows = np.broadcast_to(np.arange(k)[:, None], (k, a))
    below = np.maximum.accumulate(np.where(hit, rows, -1), axis=0)
    above = np.minimum.accumulate(np.where(hit, rows, k)[::-1], axis=0)[::-1]
    lo, hi = np.clip(below, 0, k - 1), np.clip(above, 0, k - 1)
    z_lo, z_hi = heights[lo], heights[hi]
    bridged = ~hit & (below >= 0) & (above < k) & (z_hi - z_lo <= AXIAL_FILL_SPAN_MM)
    if not bridged.any():
        return radii
    row, ray = np.nonzero(bridged)
    lo, hi = lo[row, ray], hi[row, ray]
    t = ((heights[row] - heights[lo]) / (heights[hi] - heights[lo]))[:, None]
    direction = np.column_stack([np.cos(angles[ray]), np.sin(angles[ray])])  # (b, 2)
    point = ((1.0 - t) * (origins[lo] + radii[lo, ray][:, None] * direction)
             + t * (origins[hi] + radii[hi, ray][:, None] * direction))
    out = radii.copy()
    out[row, ray] = np.einsum("bd,bd->b", point - origins[row], direction)
    return out


def _fill_polar_gaps(radii: np.ndarray, along: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Fill NaN rays of every row at once: along the leg when ``along`` gives the
    sections' heights (k,), ray origins (k, 2) and ray angles (a,) (:func:`_fill_along_axis`),
    then by periodic interpolation in the polar domain.

    A missing ray left takes the value linear in angle between the nearest hit rays on
    either side (cyclically).  Rows with fewer than ``MIN_RAY_COVERAGE`` hits of their
    own become all-NaN (missing section).  radii (k, a) -> (k, a).
    """
    k, a = radii.shape
    coverage = np.isfinite(radii).mean(axis=1)
    if along is not None and coverage.min() < 1.0:
        radii = _fill_along_axis(radii, *along)
    hit = np.isfinite(radii)
    ok = coverage >= MIN_RAY_COVERAGE
    if hit.all():
        if ok.all():
            return radii
        return np.where(ok[:, None], radii, np.nan)
    tiled = np.tile(np.where(hit, radii, 0.0), 3)
    hit3 = np.tile(hit, 3)
    j3 = np.broadcast_to(np.arange(3 * a), (k, 3 * a))
    prev = np.maximum.accumulate(np.where(hit3, j3, -1), axis=1)[:, a : 2 * a]
    nxt = np.minimum.accumulate(np.where(hit3, j3, 3 * a)[:, ::-1], axis=1)[:, ::-1][:, a : 2 * a]
    prev = np.where(ok[:, None], prev, a)
    nxt = np.where(ok[:, None], nxt, a)
    j = np.arange(a, 2 * a)[None, :]
    span = np.maximum(nxt - prev, 1)
    w = (j - prev) / span
    filled = (1.0 - w) * np.take_along_axis(tiled, prev, axis=1) + w * np.take_along_axis(tiled, nxt, axis=1)
    out = np.where(hit, radii, filled)
    out[~ok] = np.nan
    return out


def _cast_rays(plane: np.ndarray, seg: np.ndarray, centroids: np.ndarray, n_angles: int) -> np.ndarray:
    """Outermost hit radius of every (section, ray); NaN where a ray hits nothing.

    plane (s,), seg (s, 2, 2) segments; centroids (k, 2) ray origins -> (k, n_angles).
    """
    k = len(centroids)
    seg_idx, flat, r = _ray_hits(plane, seg, centroids, n_angles)
    best = np.full(k * n_angles, -np.inf)
    np.maximum.at(best, flat, r)
    best[~np.isfinite(best) | (best <= 0)] = np.nan
    return best.reshape(k, n_angles)


def _ray_hits(plane: np.ndarray, seg: np.ndarray, centroids: np.ndarray,
              n_angles: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (segment, ray) hit: the segment (h,), its (section, ray) as section *
    n_angles + ray (h,) and the hit's radius (h,) mm, for rays from each section's
    centroid (k, 2) (plane (s,), seg (s, 2, 2) as :func:`_cast_rays` takes them)."""
    a = seg[:, 0] - centroids[plane]
    b = seg[:, 1] - centroids[plane]
    theta_a = np.arctan2(a[:, 1], a[:, 0])
    dtheta = np.arctan2(b[:, 1], b[:, 0]) - theta_a
    dtheta = (dtheta + np.pi) % (2.0 * np.pi) - np.pi
    step = 2.0 * np.pi / n_angles
    theta_lo = theta_a + np.minimum(dtheta, 0.0)
    j_lo = np.ceil(theta_lo / step - 1e-12).astype(np.int64)
    j_hi = np.floor((theta_lo + np.abs(dtheta)) / step + 1e-12).astype(np.int64)
    j_hi = np.where(np.abs(dtheta) < 0.5 * np.pi, j_hi, j_lo - 1)  # skip segments through the centre
    seg_idx, ray = plane_pairs(j_lo, j_hi + 1)
    phi = ray * step
    dx, dy = np.cos(phi), np.sin(phi)
    ax, ay = a[seg_idx, 0], a[seg_idx, 1]
    abx, aby = b[seg_idx, 0] - ax, b[seg_idx, 1] - ay
    denom = dx * aby - dy * abx
    with np.errstate(invalid="ignore", divide="ignore"):
        t = -(dx * ay - dy * ax) / denom
    t = np.clip(np.nan_to_num(t, nan=0.5), 0.0, 1.0)
    r = dx * (ax + t * abx) + dy * (ay + t * aby)
    return seg_idx, plane[seg_idx] * n_angles + np.mod(ray, n_angles), r


def _segment_centroids(plane: np.ndarray, seg: np.ndarray, k: int) -> np.ndarray:
    """(k, 2) the perimeter-weighted centroid of each section's segments (plane (s,), seg
    (s, 2, 2)), mm; NaN for a section without segments."""
    length = np.hypot(*(seg[:, 1] - seg[:, 0]).T)
    mid = seg.mean(axis=1)
    total = np.bincount(plane, weights=length, minlength=k)
    centroids = np.full((k, 2), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        centroids[:, 0] = np.bincount(plane, weights=length * mid[:, 0], minlength=k) / total
        centroids[:, 1] = np.bincount(plane, weights=length * mid[:, 1], minlength=k) / total
    return centroids


#: the rays a mesh's section is tested for a hole on (5 degrees: the paper's)
HOLE_TEST_RAYS = 72
#: the sections a hole's rays are read between, this far apart, mm (sections_across_holes)
ACROSS_HOLES_STEP_MM = 3.0


def holed_sections(plane: np.ndarray, seg: np.ndarray, k: int) -> np.ndarray:
    """(k,) bool: the sections (plane (s,), seg (s, 2, 2) from :func:`mesh_section_segments`
    over k heights) with segments whose contour a ray from their centroid misses
    somewhere (one of HOLE_TEST_RAYS): a hole in the mesh (a closed contour is hit by
    every ray from inside it)."""
    raw = _cast_rays(plane, seg, np.nan_to_num(_segment_centroids(plane, seg, k)), HOLE_TEST_RAYS)
    hits = np.isfinite(raw).sum(axis=1)
    return (hits > 0) & (hits < HOLE_TEST_RAYS)


def sections_across_holes(vertices: np.ndarray, faces: np.ndarray, heights: np.ndarray,
                          n_angles: int) -> tuple[np.ndarray, np.ndarray]:
    """The centroids (h, 2) and radii (h, n_angles) mm of a mesh's sections at ``heights``
    (h,) mm whose contours have holes, read with the mesh's sections every
    ACROSS_HOLES_STEP_MM (one grid for all of them) within AXIAL_FILL_SPAN_MM / 2 above
    and below them, so that their rays through the hole are read along the leg
    (:func:`_fill_along_axis`) as far as the hole allows.  vertices (n, 3) mm, faces (f, 3)."""
    heights = np.asarray(heights, dtype=np.float64)
    grid = np.arange(heights.min() - AXIAL_FILL_SPAN_MM / 2, heights.max() + AXIAL_FILL_SPAN_MM / 2 + 1e-9,
                     ACROSS_HOLES_STEP_MM)
    stack = np.unique(np.concatenate([heights, grid]))
    sliced = slice_mesh_polar(vertices, faces, stack, n_angles)
    rows = np.searchsorted(stack, heights)
    return sliced.centroids_mm[rows], sliced.radii_mm[rows]


def slice_mesh_polar(
    vertices: np.ndarray, faces: np.ndarray, heights: np.ndarray, n_angles: int = 72, recentre: bool = True
) -> PolarSections:
    """Polar-resampled sections of a triangle mesh (see module docstring).

    vertices (n, 3) mm in the slicing frame; faces (f, 3); heights (k,) ascending mm.
    Rays start at the perimeter-weighted centroid of the section's segments; with
    ``recentre`` (default) they are cast again from the area centroid (the "weight
    center") of the gap-filled contour, which a hole in the mesh does not bias.
    """
    heights = np.asarray(heights, dtype=np.float64)
    k = len(heights)
    angles = ray_angles(n_angles)
    plane, seg = mesh_section_segments(vertices, faces, heights)
    if plane.size == 0:
        return PolarSections(heights, np.full((k, 2), np.nan), np.full((k, n_angles), np.nan), angles, np.zeros(k),
                             np.full(k, 360.0), np.full(k, np.nan))

    centroids = _segment_centroids(plane, seg, k)
    raw = _cast_rays(plane, seg, np.nan_to_num(centroids), n_angles)
    radii = _fill_polar_gaps(raw, (heights, np.nan_to_num(centroids), angles))
    if recentre:
        contour = np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=-1)
        centroids = centroids + polygon_centroid(contour)
        raw = _cast_rays(plane, seg, np.nan_to_num(centroids), n_angles)
        radii = _fill_polar_gaps(raw, (heights, np.nan_to_num(centroids), angles))
    coverage = np.isfinite(raw).mean(axis=1)
    centroids[~np.isfinite(radii).all(axis=1)] = np.nan
    radii[~np.isfinite(centroids).all(axis=1)] = np.nan
    return PolarSections(heights, centroids, radii, angles, coverage, *largest_gap(np.isfinite(raw)))


