"""A leg's first axis, before any landmark is known (paper section 2.1, step 1 of
:mod:`app.geometry.placement.leg_axis`): area-weighted PCA of the leg's surface, then
the line through the centroids of its compact (round, leg-like) slabs, which a flat foot
does not drag.  Units: mm.  Arrays: samples (n, 3) in the leg's frame, weights (n,).

Two such lines are read (:func:`first_axis`): least squares through every compact
centroid, and the line most of them lie near (a consensus, RANSAC's criterion scored
over every candidate pair: Fischler and Bolles 1981) with least squares through those.
The centroids of parallel sections of a straight limb lie on its axis whatever the
slabs' tilt, and the compact slabs that are not the limb's (a heel's or an instep's cut
obliquely by a tilted axis; a bent knee's other segment) lie off that line.  Least
squares is pulled by them, and iterated it can cycle: on robustness 220 13's
sparse_leg_vertices-04 (a knee-high vertex cloud, whose dense foot tilts the PCA) it
went 10, 23, 5.6, 19 degrees off the shank, and the landmarks were looked for along a
21-degree axis that cut the knee's sections open.  The consensus line follows one
segment of a bent knee, where least squares follows the diagonal of its L, along which
a bent knee's landmarks are found and its bend then measured
(:mod:`app.geometry.placement.knee_bend`); so least squares is read first (every leg
it places, it places as before), and the consensus line only when that reading and a
bent knee's runs have failed without finding the knee bent
(:func:`app.geometry.placement.leg_axis._consensus_reading`).
"""

from __future__ import annotations

import numpy as np

from app.geometry.placement import calf_frame as cf

#: slabs of the surface whose spread is rounder than this (major/minor axis) are leg-like;
#: a 55 x 40 mm ellipse is 1.4, a footprint 2.5 or more
COMPACT_RATIO = 1.6
SLAB_MM = 5.0
PCA_SAMPLES = 30_000
CENTROID_LINE_ITERATIONS = 4
#: a compact centroid within this of a candidate line lies on it, mm: a shank's centroid
#: line bows backwards by up to ~10 mm at the calf's bulge and below the knee (the
#: hamstring tendons and condyles, straight_reading.section_centre_line), while a heel's or a
#: bent knee's thigh slab lies tens of mm off it
LINE_INLIER_MM = 12.0
#: candidate lines join two centroids at least this far apart along the axis, mm: 1 mm of
#: centroid noise then turns a candidate by under 1 degree
LINE_BASE_MM = 60.0
#: at most this many centroids (every k-th) make candidate pairs; every compact centroid
#: votes (48 give ~1,100 candidates, each scored over ~180 slabs of a whole leg)
LINE_CANDIDATES = 48
#: an axis is taken as found when an iteration moves it less than this, degrees (the
#: calf axis's re-estimation, straight_reading.refine, stops by the same tolerance)
AXIS_TOLERANCE_DEG = 0.5


def pca_samples(points: np.ndarray, faces: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """Area-weighted surface samples, thinned by a fixed stride of floor(n / 30,000) (so
    30k-60k of a large scan; the principal axes of 30k samples of a leg agree with all
    of them to ~0.1 degree)."""
    samples, weights = cf.surface_samples(points, faces)
    stride = max(len(samples) // PCA_SAMPLES, 1)
    return samples[::stride], None if weights is None else weights[::stride]


def centroid_line_axis(local_samples: np.ndarray, weights: np.ndarray | None,
                       consensus: bool = False) -> np.ndarray | None:
    """Direction (3,), in the samples' frame, of the line through the centroids of the
    compact slabs of the surface.

    The surface samples are binned into :data:`SLAB_MM` slabs along z; each slab's
    weighted centroid and 2x2 covariance are accumulated with bincount.  A slab counts
    as leg-like when its spread is nearly round (sqrt of the eigenvalue ratio below
    :data:`COMPACT_RATIO`): a shin is, a footprint is not.  The line is least squares
    through those centroids, or with ``consensus`` through the ones on their consensus
    line (:func:`consensus_line`).  Returns None when fewer than 10 slabs qualify.
    """
    w = np.ones(len(local_samples)) if weights is None else weights
    z = local_samples[:, 2]
    slab = np.floor((z - z.min()) / SLAB_MM).astype(np.int64)
    n = int(slab.max()) + 1
    total = np.bincount(slab, weights=w, minlength=n)
    keep = total > 0
    moments = {}
    x, y = local_samples[:, 0], local_samples[:, 1]
    for name, values in (("x", x), ("y", y), ("xx", x * x), ("yy", y * y), ("xy", x * y), ("z", z)):
        moments[name] = np.bincount(slab, weights=w * values, minlength=n)[keep] / total[keep]
    cxx = moments["xx"] - moments["x"] ** 2
    cyy = moments["yy"] - moments["y"] ** 2
    cxy = moments["xy"] - moments["x"] * moments["y"]
    half_trace, det = (cxx + cyy) / 2, cxx * cyy - cxy**2
    root = np.sqrt(np.maximum(half_trace**2 - det, 0.0))
    small, large = half_trace - root, half_trace + root
    compact = (small > 0) & (large < COMPACT_RATIO**2 * np.maximum(small, 1e-12))
    if compact.sum() < 10:
        return None
    centres = np.column_stack([moments["x"], moments["y"], moments["z"]])[compact]
    slab_weights = total[keep][compact]
    if consensus:
        on_line = consensus_line(centres)
        centres, slab_weights = centres[on_line], slab_weights[on_line]
    direction = cf.principal_axis(centres, slab_weights)
    return direction if direction[2] > 0 else -direction


def consensus_line(centres: np.ndarray) -> np.ndarray:
    """Which of the slab ``centres`` (s, 3; z ascending, mm) lie on the line most of
    them lie near (bool (s,)): every line through two centres at least LINE_BASE_MM
    apart in z (of up to LINE_CANDIDATES of them) is scored by how many centres lie
    within LINE_INLIER_MM of it, and the best one's (the first of equals) are returned
    (RANSAC's consensus, Fischler and Bolles 1981, over every candidate instead of random
    ones, so the same scan gives the same line).  All of them when no two lie that far
    apart."""
    stride = max(int(np.ceil(len(centres) / LINE_CANDIDATES)), 1)
    candidates = centres[::stride]
    first, second = np.triu_indices(len(candidates), 1)
    apart = candidates[second, 2] - candidates[first, 2] >= LINE_BASE_MM
    if not apart.any():
        return np.ones(len(centres), dtype=bool)
    origin = candidates[first[apart]]  # (p, 3)
    direction = candidates[second[apart]] - origin
    direction /= np.linalg.norm(direction, axis=1)[:, None]
    # squared distance of every centre from every candidate line (p, s): |r|^2 - (r . d)^2
    offset = centres[None, :, :] - origin[:, None, :]
    along = np.einsum("psk,pk->ps", offset, direction)
    distance2 = np.einsum("psk,psk->ps", offset, offset) - along**2
    near = distance2 < LINE_INLIER_MM**2
    return near[int(np.argmax(near.sum(axis=1)))]


def first_axis(samples: np.ndarray, weights: np.ndarray | None, shape_axes: np.ndarray,
               up: np.ndarray | None, consensus: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(axis (3,), basis (3, 3)) of a leg from its surface ``samples`` (n, 3) and their
    ``weights`` (n,) or None: the principal axis of ``shape_axes`` (3, 3; rows, the
    last the longest), turned towards ``up`` (3,) when known, then moved to the line
    through the compact slabs' centroids (:func:`centroid_line_axis`, least squares or
    with ``consensus`` the consensus line's) at most CENTROID_LINE_ITERATIONS times or
    until it moves less than AXIS_TOLERANCE_DEG."""
    axis = shape_axes[2]
    if up is not None and axis @ up < 0:
        axis = -axis
    centre = samples.mean(axis=0)
    basis = cf.perpendicular_basis(axis, shape_axes[1])
    # a flat foot drags the PCA axis; the line through the centroids of the compact
    # (leg-like, not footprint-like) slabs of the surface does not
    for _ in range(CENTROID_LINE_ITERATIONS):
        line = centroid_line_axis((samples - centre) @ basis.T, weights, consensus)
        if line is None:
            break
        new_axis = basis.T @ line
        if new_axis @ axis < 0:
            new_axis = -new_axis
        moved = cf.angle_deg(new_axis, axis)
        axis = new_axis
        basis = cf.perpendicular_basis(axis, basis[1])
        if moved < AXIS_TOLERANCE_DEG:
            break
    return axis, basis
