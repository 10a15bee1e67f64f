"""Leg selection, PCA orientation and the calf frame (paper section 2.1).

Calf frame (mm): origin on the calf axis at the ankle height B; z along the leg towards
the knee; y anterior; x = y cross z (right-handed), which points to the subject's right.
:class:`CalfFrame` records the rigid transform from the scan's millimetres and the
4x4 matrix back to the scan's own coordinates and units.

Whole bodies (longer than :data:`BODY_MIN_LENGTH_MM`): the feet end is the end whose
slab splits into two blobs; both legs are cut below 40% of the body length (hands hang
higher than that: ANSUR/README fingertip heights >= 43%) and separated by 2-means on
the shins; left and right follow from the anterior direction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from sklearn.cluster import KMeans

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.scan.sampling import area_weights

BODY_MIN_LENGTH_MM = 1300.0
LEG_REGION_FRACTION = 0.40


@dataclass(frozen=True)
class CalfFrame:
    """Rigid placement of the calf frame in the scan.

    Attributes
    ----------
    rotation : (3, 3) float64
        Rows are the calf axes x, y (anterior), z (up the leg) in scan-mm coordinates.
    origin_mm : (3,) float64
        Calf-frame origin in scan-mm coordinates.
    mm_per_unit : float
        Millimetres per scan unit (1, 10 or 1000).
    anterior_cue : str
        ``"foot"`` or ``"calf_bulge"``: what told front from back.
    """

    rotation: np.ndarray
    origin_mm: np.ndarray
    mm_per_unit: float
    anterior_cue: str

    def to_calf(self, points_mm: np.ndarray) -> np.ndarray:
        """(n, 3) scan-mm points -> (n, 3) calf-frame mm."""
        return (points_mm - self.origin_mm) @ self.rotation.T

    def matrix(self) -> np.ndarray:
        """(4, 4) homogeneous matrix: calf-frame mm -> scan coordinates in scan units."""
        m = np.eye(4)
        m[:3, :3] = self.rotation.T / self.mm_per_unit
        m[:3, 3] = self.origin_mm / self.mm_per_unit
        return m


def principal_axis(points: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """First principal component (PCA) of (n, 3) points; returns a unit (3,) vector."""
    if weights is None:
        centred = points - points.mean(axis=0)
        cov = centred.T @ centred
    else:
        w = weights / weights.sum()
        centred = points - w @ points
        cov = (centred * w[:, None]).T @ centred
    _, vectors = np.linalg.eigh(cov)
    return vectors[:, -1]


def surface_samples(points: np.ndarray, faces: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """Points standing for the surface evenly: triangle centroids with their areas as
    weights for a mesh (so a densely meshed knee does not tilt the PCA), the points
    themselves for a cloud.  Returns (s, 3) samples and (s,) weights or None."""
    if faces is None or not len(faces):
        return points, None
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    e1, e2 = b - a, c - a
    nx = e1[:, 1] * e2[:, 2] - e1[:, 2] * e2[:, 1]
    ny = e1[:, 2] * e2[:, 0] - e1[:, 0] * e2[:, 2]
    nz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    area = 0.5 * np.sqrt(nx * nx + ny * ny + nz * nz)
    return (a + b + c) / 3.0, area


def principal_frame(points: np.ndarray, weights: np.ndarray | None = None) -> np.ndarray:
    """(3, 3) rows: principal axes of (n, 3) points, largest variance last (z).

    Each axis' sign is fixed by the sign of the third moment along it, so the frame
    turns with the scan (no dependence on the scan's own axes); the first row is
    re-derived so the frame is right-handed.  Optional (n,) weights.
    """
    w = np.ones(len(points)) if weights is None else weights / weights.sum() * len(points)
    centred = points - (w @ points) / w.sum()
    _, vectors = np.linalg.eigh((centred * w[:, None]).T @ centred)
    axes = vectors.T[::-1][[1, 2, 0]]  # second, third, first component -> x, y, z
    skew = (w[:, None] * (centred @ axes.T) ** 3).mean(axis=0)
    axes = axes * np.where(skew < 0, -1.0, 1.0)[:, None]
    axes[0] = np.cross(axes[1], axes[2])
    return axes


def perpendicular_basis(axis: np.ndarray, hint: np.ndarray | None = None) -> np.ndarray:
    """(3, 3) rotation whose rows x, y, z are right-handed with z = axis.

    ``hint`` (optional) is projected to give y.
    """
    z = axis / np.linalg.norm(axis)
    if hint is None or np.linalg.norm(hint - (hint @ z) * z) < 1e-9:
        hint = np.eye(3)[np.argmin(np.abs(z))]
    y = hint - (hint @ z) * z
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    return np.stack([x, y, z])


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


#: two legs side by side: at least this share of the slabs 10-50% of the length from
#: the feet end hold two blobs of comparable size (the smaller at least 30% of the larger)
TWO_LEG_SLAB_SHARE = 0.7
TWO_LEG_MIN_LENGTH_MM = 500.0
SHIN_GAP_MM = 10.0


def _shin_side_coordinate(local: np.ndarray, shins: np.ndarray, apart: bool) -> np.ndarray | None:
    """Signed distance (n,) of every point from the mid-plane between the two shins.

    The shin points (``shins`` mask over local (n, 3)) are split by 2-means; None when
    their centres are under 60 mm apart or, with ``apart``, closer than the sum of their
    radii (RMS distance from each centre) or with less than :data:`SHIN_GAP_MM` of air
    between them: two shins do not overlap, while the two halves of one shin's ring lie
    4r/pi apart with RMS radii of ~0.77 r each and touch.
    """
    shin_xy = local[shins, :2][:: max(int(shins.sum()) // 20000, 1)]
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
    from app.geometry.scan.cleanup import point_spacing

    if spacing_p95_mm is None:
        spacing_p95_mm = point_spacing(points_mm, 95.0)
    pixel = max(10.0, 2.0 * spacing_p95_mm)
    shares, pair_sizes = [], []
    for sign in (1.0, -1.0):
        pairs, sizes_near = 0, []
        fractions = np.linspace(0.10, 0.50, 9)
        for f in fractions:
            level = lo + f * length if sign > 0 else hi - f * length
            sizes = _slab_blob_sizes(local[(h >= level - 10.0) & (h < level + 10.0), :2], pixel)
            paired = sizes.size >= 2 and sizes[1] >= 0.3 * sizes[0]
            pairs += int(paired)
            if paired and f <= 0.30:
                sizes_near.append(sizes[0] + sizes[1])
        shares.append(pairs / len(fractions))
        pair_sizes.append(float(np.mean(sizes_near)) if sizes_near else np.inf)
    if max(shares) < TWO_LEG_SLAB_SHARE:
        return None
    # the feet end: two legs joined at the hips pair up from both ends (shins at one,
    # thighs at the other), so the share alone cannot tell the ends; the shins and
    # ankles 10-30% from the feet are far thinner than the thighs 10-30% from the hips
    # (ankle girth ~220 mm, thigh ~550 mm)
    if min(shares) >= TWO_LEG_SLAB_SHARE and np.isfinite(pair_sizes).all():
        sign = 1.0 if pair_sizes[0] <= pair_sizes[1] else -1.0
    else:
        sign = 1.0 if shares[0] >= shares[1] else -1.0
    height = (h - lo) if sign > 0 else (hi - h)
    side_coord = _shin_side_coordinate(local, (height > 0.10 * length) & (height < 0.40 * length), True)
    if side_coord is None:
        return None
    # two legs are both (nearly) the length of the scan; a foot beside a shin is not
    for half in (side_coord < 0, side_coord >= 0):
        if np.ptp(h[half]) < 0.6 * length:
            return None
    up = sign * basis[2]
    return LegCut(np.flatnonzero(side_coord < 0), up), LegCut(np.flatnonzero(side_coord >= 0), up)


@dataclass(frozen=True)
class LegCut:
    """The vertices of one leg cut out of a body: ``point_index`` (n,), ``up`` (3,)."""

    point_index: np.ndarray
    up: np.ndarray


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
        from app.geometry.scan.cleanup import point_spacing

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


def submesh(point_index: np.ndarray, faces: np.ndarray | None, n_points: int) -> np.ndarray | None:
    """Faces whose three corners are all in ``point_index``, renumbered; None for clouds."""
    if faces is None:
        return None
    remap = np.full(n_points, -1, dtype=np.int64)
    remap[point_index] = np.arange(len(point_index))
    mapped = remap[faces]
    return mapped[(mapped >= 0).all(axis=1)]


def anterior_from_foot(calf_points: np.ndarray, ankle_centre_xy: np.ndarray, ankle_radius: float) -> np.ndarray | None:
    """Direction (2,) from the ankle axis to the foot's mass, or None when no foot.

    calf_points (n, 3) in a provisional frame with z = 0 at B and z up the leg.  The foot
    is the part more than 40 mm below B; it counts when it reaches further than 1.5
    ankle radii from the ankle axis (a heel and toes, not just a stump).  The mass is
    the skin's, each point weighted by its share of the skin's area
    (:func:`app.geometry.scan.sampling.area_weights`): the points' own mean leaned to
    the side a scanner sampled densely, and a cloud 4 times sparser on one side turned
    the frame by up to 11 degrees - enough to read a right foot as a left one with a
    confidence of 0.99999 (benchmarks/robustness.py 220 7, cloud_uneven-02 and -05).
    """
    below = calf_points[:, 2] < -40.0
    foot = calf_points[below, :2] - ankle_centre_xy
    if len(foot) < 50:
        return None
    reach = np.linalg.norm(foot, axis=1)
    if np.percentile(reach, 95) < 1.5 * ankle_radius:
        return None
    weight = area_weights(calf_points[below])
    direction = (foot * weight[:, None]).sum(axis=0) / weight.sum()
    norm = np.linalg.norm(direction)
    return direction / norm if norm > 5.0 else None


def anterior_from_calf_bulge(centroids_xy: np.ndarray, heights: np.ndarray, c_mm: float) -> np.ndarray | None:
    """Anterior (2,) as opposite the calf bulge: the C centroid's offset from the B-D line.

    centroids_xy (k, 2), heights (k,) of sections from B (first) to D (last).
    """
    t = (c_mm - heights[0]) / (heights[-1] - heights[0])
    on_line = (1 - t) * centroids_xy[0] + t * centroids_xy[-1]
    ic = int(np.argmin(np.abs(heights - c_mm)))
    offset = centroids_xy[ic] - on_line
    norm = np.linalg.norm(offset)
    return -offset / norm if norm > 0.5 else None
