"""The legs of a whole body or of two legs joined at the hips, cut apart (paper section
2.1 measures one leg; clinics send bodies and pairs).

Whole bodies (longer than :data:`BODY_MIN_LENGTH_MM`): the feet end is the end whose
slab splits into two blobs; both legs are cut below 40% of the body length (hands hang
higher than that: ANSUR/README fingertip heights >= 43%) and separated by 2-means on
the shins; left and right follow from the anterior direction.  Two legs joined at the
hips (:func:`split_two_legs`): two shins side by side in the slabs 10-50% of the length
from the feet.  :func:`split_legs` picks between them and, for a coarse mesh, splits on
points sampled on its triangles.  Units: mm; arrays (n, 3) points.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy import ndimage
from sklearn.cluster import KMeans

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.placement.calf_frame import perpendicular_basis, principal_axis
from app.geometry.scan.cleanup import point_spacing

BODY_MIN_LENGTH_MM = 1300.0
LEG_REGION_FRACTION = 0.40


def _slab_blob_sizes(points_2d: np.ndarray, pixel_mm: float = 10.0) -> np.ndarray:
    """Sizes (occupied pixels, descending) of the separate blobs of (n, 2) points on a
    coarse occupancy grid."""
    if len(points_2d) < 10:
        return np.zeros(0, dtype=np.int64)
    cells = np.floor((points_2d - points_2d.min(axis=0)) / pixel_mm).astype(np.int64)
    grid = np.zeros(cells.max(axis=0) + 3, dtype=bool)
    grid[cells[:, 0] + 1, cells[:, 1] + 1] = True
    grid = ndimage.binary_closing(grid, iterations=1)
    labels, count = ndimage.label(grid)
    return np.sort(np.bincount(labels.ravel())[1:])[::-1]


def _slab_blob_count(points_2d: np.ndarray, pixel_mm: float = 10.0) -> int:
    """Number of separate blobs of (n, 2) points on a coarse occupancy grid."""
    sizes = _slab_blob_sizes(points_2d, pixel_mm)
    if not sizes.size:
        return 0
    return int((sizes >= max(3, 0.05 * sizes.max())).sum())


#: two touching legs: the section's depth across the line through the two lobes at the
#: point midway between them, against the mean depth through the lobes' centres, is
#: below this (a convex section's is at least 1: its chords in one direction have a
#: concave length along the line, Brunn-Minkowski in the plane)
TOUCHING_WAIST_RATIO = 0.7
#: ... and each lobe is a leg's ring round its centre: no gap in the directions of its
#: points seen from its centre wider than this (the half of one ring spans 226 degrees
#: from its centroid, a gap of 134; a leg pressed on the other misses its contact, a
#: 60-degree arc where it is pressed flat over half its diameter)
LOBE_MAX_GAP_DEG = 110.0


def _two_touching_lobes(points_2d: np.ndarray, band_mm: float) -> bool:
    """Whether a slab's (n, 2) points (mm) are two legs' sections that touch: two lobes
    side by side with a waist between them.

    The points are halved across their principal direction at the mean; the lobes are
    the halves, of comparable size (the smaller at least 30% of the larger, as the
    blobs).  The depth of the section across that direction (the spread of the points
    within ``band_mm`` of a position along it) midway between the lobes' centres is
    under TOUCHING_WAIST_RATIO of the mean depth through the centres, with points on
    both sides of the line (a view from one side, a C, has its middle on one side only)
    or none at all (air narrower than the blobs' pixel),
    and each lobe surrounds its own centre (no angular gap over LOBE_MAX_GAP_DEG): one
    section of one leg, even elongated or seen from one side, is not two lobes.
    """
    if len(points_2d) < 40:
        return False
    centred = points_2d - points_2d.mean(axis=0)
    _, _, vt = np.linalg.svd(centred[:: max(len(centred) // 5000, 1)], full_matrices=False)
    along, across = centred @ vt[0], centred @ vt[1]
    halves = [along < 0, along >= 0]
    sizes = np.array([h.sum() for h in halves])
    if sizes.min() < 0.3 * sizes.max():
        return False
    centres = [np.array([along[h].mean(), across[h].mean()]) for h in halves]
    middle = 0.5 * (centres[0] + centres[1])

    def depth(at: float) -> np.ndarray:
        return across[np.abs(along - at) <= band_mm]

    waist = depth(middle[0])
    through = [depth(c[0]) for c in centres]
    if min(len(t) for t in through) < 3:
        return False
    if len(waist):  # (none: air between the lobes, closer than the blobs' pixel)
        line = middle[1]
        if not ((waist < line).any() and (waist > line).any()):
            return False
        if np.ptp(waist) >= TOUCHING_WAIST_RATIO * np.mean([np.ptp(t) for t in through]):
            return False
    for half, centre in zip(halves, centres):
        angles = np.sort(np.arctan2(across[half] - centre[1], along[half] - centre[0]))
        gaps = np.diff(np.r_[angles, angles[0] + 2 * np.pi])
        if np.degrees(gaps.max()) > LOBE_MAX_GAP_DEG:
            return False
    return True


#: two legs side by side: at least this share of the slabs 10-50% of the length from
#: the feet end hold two blobs of comparable size (the smaller at least 30% of the larger)
TWO_LEG_SLAB_SHARE = 0.7
TWO_LEG_MIN_LENGTH_MM = 500.0
SHIN_GAP_MM = 10.0


def _shin_side_coordinate(local: np.ndarray, shins: np.ndarray, apart: bool, along_legs: bool = False) -> np.ndarray | None:
    """Signed distance (n,) of every point from the mid-plane between the two shins.

    The shin points (``shins`` mask over local (n, 3)) are split by 2-means; None when
    their centres are under 60 mm apart or, with ``apart``, closer than the sum of their
    radii (RMS distance from each centre) or with less than :data:`SHIN_GAP_MM` of air
    between them: two shins do not overlap, while the two halves of one shin's ring lie
    4r/pi apart with RMS radii of ~0.77 r each and touch.

    The mid-plane holds the scan's main axis (local z) or, ``along_legs``, the bisector
    of the two legs' own axes (each cluster's principal direction, in 3D): the plane of
    symmetry of two legs standing apart, which the main axis of a pair with one leg cut
    short is not (the whole leg's foot and ankle tilt it towards that leg, and a plane
    holding it, drawn from the knees, cut through that foot).
    """
    shin_3d = local[shins][:: max(int(shins.sum()) // 20000, 1)]
    shin_xy = shin_3d[:, :2]
    km = KMeans(n_clusters=2, n_init=3, random_state=0).fit(shin_xy)
    c0, c1 = km.cluster_centers_
    gap = np.linalg.norm(c1 - c0)
    if gap < 60.0:
        return None
    if apart:
        spread = [np.sqrt(((shin_xy[km.labels_ == i] - c) ** 2).sum(axis=1).mean()) for i, c in enumerate((c0, c1))]
        if gap < sum(spread):
            return None
        # and a gap of air between them: the nearest points of the two shins are at least
        # SHIN_GAP_MM apart (two halves of one ring touch at the split)
        from scipy.spatial import cKDTree

        nearest, _ = cKDTree(shin_xy[km.labels_ == 0]).query(shin_xy[km.labels_ == 1], k=1)
        if nearest.min() < SHIN_GAP_MM:
            return None
    if along_legs:
        centres, directions = [], []
        for label in (0, 1):
            leg = shin_3d[km.labels_ == label]
            centre = leg.mean(axis=0)
            direction = np.linalg.svd(leg - centre, full_matrices=False)[2][0]
            centres.append(centre)
            directions.append(direction if direction[2] >= 0 else -direction)
        along = (directions[0] + directions[1]) / np.linalg.norm(directions[0] + directions[1])
        across = (centres[1] - centres[0]) - ((centres[1] - centres[0]) @ along) * along
        return (local - 0.5 * (centres[0] + centres[1])) @ (across / np.linalg.norm(across))
    return (local[:, :2] - 0.5 * (c0 + c1)) @ ((c1 - c0) / gap)


def split_two_legs(points_mm: np.ndarray, spacing_p95_mm: float | None = None) -> tuple[LegCut, LegCut] | None:
    """Two legs joined at the hips (feet to hips, shorter than a body), cut apart; None
    when the scan is not two legs.

    Two legs stand side by side: in slabs across the main axis between 10% and 50% of
    the length from the feet end, two blobs of comparable size (two shins; a single
    leg, even bent at the knee, gives one blob per slab at its ends).  The shins are then
    separated by 2-means and every point goes to the nearer side of the mid-plane.
    ``spacing_p95_mm``: the 95th percentile of the scan's point spacing, when known.
    """
    centre = points_mm.mean(axis=0)
    basis = perpendicular_basis(principal_axis(points_mm[:: max(len(points_mm) // 20000, 1)]))
    local = (points_mm - centre) @ basis.T
    h = local[:, 2]
    lo, hi = h.min(), h.max()
    length = hi - lo
    if length < TWO_LEG_MIN_LENGTH_MM:
        return None
    # the occupancy pixel must bridge the gaps between the points of one ring, or a sparse
    # mesh's shin falls apart into arcs: twice the 95th percentile of the point spacing
    # (meshes are denser at the joints than along the shin)
    if spacing_p95_mm is None:
        spacing_p95_mm = point_spacing(points_mm, 95.0)
    pixel = max(10.0, 2.0 * spacing_p95_mm)
    band = max(3.0, spacing_p95_mm)
    fractions = np.linspace(0.10, 0.50, 9)
    # per end (the low end first) and slab: two blobs of comparable size; and, only when
    # the blobs split neither end, two touching lobes where there are no two blobs
    blobs, lobes, sizes_near = np.zeros((2, 9), bool), np.zeros((2, 9), bool), np.zeros((2, 9))
    slabs = {}
    for end, sign in enumerate((1.0, -1.0)):
        for k, f in enumerate(fractions):
            level = lo + f * length if sign > 0 else hi - f * length
            slabs[end, k] = local[(h >= level - 10.0) & (h < level + 10.0), :2]
            sizes = _slab_blob_sizes(slabs[end, k], pixel)
            blobs[end, k] = sizes.size >= 2 and sizes[1] >= 0.3 * sizes[0]
            sizes_near[end, k] = sizes[:2].sum() if sizes.size else 0
    near = fractions <= 0.30
    blob_shares = blobs.mean(axis=1)
    if blob_shares.max() < TWO_LEG_SLAB_SHARE:
        for end, k in zip(*np.nonzero(~blobs & (sizes_near > 0))):
            lobes[end, k] = _two_touching_lobes(slabs[end, k], band)
    if blob_shares.max() >= TWO_LEG_SLAB_SHARE:
        shares, paired, apart = blob_shares, blobs, True
    elif (blobs | lobes).mean(axis=1).min() >= TWO_LEG_SLAB_SHARE:
        # legs that touch (feet together): no air between them, so the blobs merge; their
        # slabs' waists tell them apart.  Both ends must pair then (the thighs too, air
        # or a waist between them): one leg beside a thigh cut short pairs at the thighs'
        # end only, and would be cut down the middle of its shin as if that were two
        shares, paired, apart = (blobs | lobes).mean(axis=1), blobs | lobes, False
    else:
        return None
    pair_sizes = [float(sizes_near[end][paired[end] & near].mean()) if (paired[end] & near).any() else np.inf
                  for end in (0, 1)]
    # the feet end: two legs joined at the hips pair up from both ends (shins at one,
    # thighs at the other), so the share alone cannot tell the ends; the shins and
    # ankles 10-30% from the feet are far thinner than the thighs 10-30% from the hips
    # (ankle girth ~220 mm, thigh ~550 mm)
    # ... and where only one end pairs, it is the thinner end still: the ends' sections
    # 10-30% from them, paired or not, one ankle or two against two thighs.  Only one end
    # pairs when the legs touch at the other (thighs together: the shins pair) or when
    # one leg is cut short above its ankle (a knee-high stump: the thighs pair, and the
    # shins' end holds a single shin in 2-4 of its 5 slabs); the share of paired slabs
    # named the thighs' end the feet's then and cut down between the thighs, which touch,
    # so the pair was not cut apart and the whole leg was refused with the stump beside
    # it as one leg (benchmarks/other_leg.py 16 11: 3 of 16 legs cut 159-169 mm above
    # the sole, refused as bent knees or partial views)
    thickness = sizes_near[:, near].mean(axis=1)  # (2,) occupied pixels per slab near each end
    if shares.min() >= TWO_LEG_SLAB_SHARE and np.isfinite(pair_sizes).all():
        sign = 1.0 if pair_sizes[0] <= pair_sizes[1] else -1.0
    elif (thickness > 0).all():
        sign = 1.0 if thickness[0] <= thickness[1] else -1.0
    else:
        sign = 1.0 if shares[0] >= shares[1] else -1.0
    height = (h - lo) if sign > 0 else (hi - h)
    # the shins are the band from the feet end's lowest slab that holds both legs, 30% of
    # the length long: 10-40% from the feet when both shins reach the ankles; higher up
    # when one leg is cut short above its ankle (2-means on one shin and a stump's bottom
    # finds no two legs with air between them, and the pair was refused as one leg)
    feet = 0 if sign > 0 else 1
    first = float(fractions[np.argmax(paired[feet])]) if paired[feet].any() else 0.10
    # (shins that touch have no air between them: their slabs' waists told them apart)
    side_coord = _shin_side_coordinate(local, (height > first * length) & (height < (first + 0.30) * length), apart,
                                       along_legs=first > fractions[0])
    if side_coord is None:
        return None
    # two legs are both (nearly) the length of the scan; a foot beside a shin is not
    for half in (side_coord < 0, side_coord >= 0):
        if np.ptp(h[half]) < 0.6 * length:
            return None
    up = sign * basis[2]
    return (LegCut(np.flatnonzero(side_coord < 0), up, not apart),
            LegCut(np.flatnonzero(side_coord >= 0), up, not apart))


@dataclass(frozen=True)
class LegCut:
    """The vertices of one leg cut out of a body: ``point_index`` (n,), ``up`` (3,);
    ``touching``: the legs touched, and were told apart by their sections' waists."""

    point_index: np.ndarray
    up: np.ndarray
    touching: bool = False


def body_end_pixel(spacing_p95_mm: float) -> float:
    """Occupancy pixel (mm) for the blobs of a body's end slab: 10 mm, or the 95th
    percentile of the point spacing when that is larger.  Points at most one pixel
    apart fall in touching cells, and the grid's closing bridges one more empty pixel,
    so one foot stays one blob; two feet stand 60 mm or more apart at the ankles (the
    shins' test above), which a pixel up to 30 mm (the coarsest meshes the service
    accepts for bodies) still leaves at least one empty pixel between."""
    return max(10.0, float(spacing_p95_mm))


def split_body_legs(points_mm: np.ndarray, spacing_p95_mm: float | None = None) -> tuple[LegCut, LegCut]:
    """Cut the two legs out of a whole-body scan (see module docstring).

    points_mm (n, 3); ``spacing_p95_mm`` the 95th percentile of its point spacing, when
    known.  Returns the two legs in arbitrary order, each with the unit ``up`` vector
    (feet -> head).  Raises FitFailure SIDE_NOT_FOUND when the feet or two separate legs
    cannot be found.

    The feet are the end whose slab holds two blobs.  The occupancy pixel scales with the
    point spacing (:func:`body_end_pixel`): a fixed 10 mm pixel breaks a coarse mesh's
    feet (vertices 20-40 mm apart) into specks that are not counted as blobs.
    """
    centre = points_mm.mean(axis=0)
    basis = perpendicular_basis(principal_axis(points_mm))
    local = (points_mm - centre) @ basis.T
    h = local[:, 2]
    lo, hi = h.min(), h.max()
    length = hi - lo
    if spacing_p95_mm is None:
            spacing_p95_mm = point_spacing(points_mm, 95.0)
    pixel = body_end_pixel(spacing_p95_mm)
    # the end slab is at least two point spacings thick, so a coarse mesh's feet have
    # vertices in it (5% of a body is ~85 mm)
    slab = max(0.05 * length, 2.0 * spacing_p95_mm)
    blobs_low = _slab_blob_count(local[h < lo + slab, :2], pixel)
    blobs_high = _slab_blob_count(local[h > hi - slab, :2], pixel)
    if blobs_low >= 2 and blobs_high < 2:
        sign = 1.0
    elif blobs_high >= 2 and blobs_low < 2:
        sign = -1.0
    else:
        raise FitFailure(
            FailureReason.SIDE_NOT_FOUND,
            "this looks like a whole body but its two feet could not be told from its head",
        )
    height = (h - lo) if sign > 0 else (hi - h)
    leg_region = height < LEG_REGION_FRACTION * length
    side_coord = _shin_side_coordinate(local, (height > 0.08 * length) & (height < 0.25 * length), False)
    if side_coord is None:
        raise FitFailure(FailureReason.SIDE_NOT_FOUND, "the two legs of this body scan could not be separated")
    up = sign * basis[2]
    return (
        LegCut(np.flatnonzero(leg_region & (side_coord < 0)), up),
        LegCut(np.flatnonzero(leg_region & (side_coord >= 0)), up),
    )


#: a mesh whose vertices lie further apart than this (p95, mm) is split into its legs on
#: points sampled on its triangles SPLIT_SAMPLE_SPACING_MM apart (:func:`split_legs`)
SPLIT_SPARSE_VERTICES_MM = 5.0
SPLIT_SAMPLE_SPACING_MM = 4.0
#: ... at most this many (a body's skin, ~2 m^2, at 4 mm would be 125k)
MAX_SPLIT_SAMPLES = 60_000


def split_legs(points: np.ndarray, faces: np.ndarray | None, spacing_p95_mm: float | None = None):
    """The legs of a whole body or of two legs joined at the hips; None for one leg.
    points (n, 3) mm, faces (f, 3) or None; ``spacing_p95_mm``: the scan's point spacing
    when the clean-up measured it (a cloud's).

    The split finds the legs as separate blobs of occupied pixels in slabs across the
    body, the pixel twice the points' spacing (p95) so that one leg's ring of points
    stays one blob.  A mesh's ring is closed by its triangles, not by its vertices: a
    coarse mesh's vertices lie 20-40 mm apart (edges up to 75 mm), and a pixel twice
    that (41 mm on benchmarks/robustness.py 220 17, coarse_mesh-01, closed once more)
    merges two shins standing 30-80 mm apart into one blob, so two legs were read as one
    and refused as a partial view.  A mesh whose vertices lie more than
    SPLIT_SPARSE_VERTICES_MM apart (p95; the pixel would pass its 10 mm floor) is split
    on its vertices and points sampled on its triangles (trimesh.sample.sample_surface,
    seeded: the same mesh splits alike when a placement is replayed), each vertex going
    with the leg the split gives it.  A piece shorter than TWO_LEG_MIN_LENGTH_MM along its
    main axis (PCA of a 20k-point subsample) is one leg, measured before any spacing (a
    knee-high scan's mesh is not searched for a pair); one longer than
    BODY_MIN_LENGTH_MM is a whole body."""
    length = float(np.ptp(points @ principal_axis(points[:: max(len(points) // 20000, 1)]))) if len(points) else 0.0
    if length < TWO_LEG_MIN_LENGTH_MM:
        return None
    occupancy = points
    if faces is not None and len(faces):
        spacing_p95_mm = point_spacing(points, 95.0)
        if spacing_p95_mm > SPLIT_SPARSE_VERTICES_MM:
            mesh = trimesh.Trimesh(points, faces, process=False)
            count = int(min(mesh.area / SPLIT_SAMPLE_SPACING_MM**2, MAX_SPLIT_SAMPLES))
            occupancy = np.vstack([points, trimesh.sample.sample_surface(mesh, count, seed=0)[0]])
            spacing_p95_mm = point_spacing(occupancy, 95.0)
    split = split_body_legs if length >= BODY_MIN_LENGTH_MM else split_two_legs
    cuts = split(occupancy, spacing_p95_mm)
    if cuts is None or occupancy is points:
        return cuts
    return tuple(LegCut(cut.point_index[cut.point_index < len(points)], cut.up, cut.touching) for cut in cuts)
