"""Polar sections: :class:`PolarSections` (radii on rays from each section's centroid,
paper section 2.1, Figure 2) and the plane geometry of such contours (ray angles,
perimeter, area centroid, the largest arc without skin, a missing section bridged from its
neighbours).  Units: mm.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

#: the largest arc without skin a section may have and still be measured, degrees (a
#: cloud's section with a larger one is missing, app.geometry.sections.cloud): a 40 mm
#: hole spans 40 / r radians, 76 degrees at a 30 mm ankle radius (the smallest ANSUR II
#: ankle girth, 156 mm, has r = 25 mm: 92 degrees); a section seen over less than 260
#: degrees is not a scan of that section
MAX_GAP_DEG = 100.0

@dataclass(frozen=True)
class PolarSections:
    """Cross-sections resampled on a polar grid.

    Attributes
    ----------
    heights_mm : (k,) float64
        Plane heights (z) in the slicing frame, ascending.
    centroids_mm : (k, 2) float64
        Section centroid (x, y); NaN for missing sections.
    radii_mm : (k, a) float64
        Radius of the outer contour along each ray; NaN rows for missing sections.
    angles_rad : (a,) float64
        Ray angles, ``2*pi*j/a``.
    coverage : (k,) float64
        Fraction of rays that hit the contour directly (1.0 for a closed mesh).
    largest_gap_deg : (k,) float64 or None
        The largest arc around the section's centre without a ray hit (a mesh) or an
        angular bin holding points (a cloud), degrees: 360 where the plane has nothing.
        None where the slicer did not measure it.
    gap_middle_rad : (k,) float64 or None
        The angle of that arc's middle (NaN without a gap).
    """

    heights_mm: np.ndarray
    centroids_mm: np.ndarray
    radii_mm: np.ndarray
    angles_rad: np.ndarray
    coverage: np.ndarray
    largest_gap_deg: np.ndarray | None = None
    gap_middle_rad: np.ndarray | None = None

    @property
    def valid(self) -> np.ndarray:
        """(k,) bool: sections with a usable contour."""
        return np.isfinite(self.radii_mm).all(axis=1)

    def open_arcs(self) -> np.ndarray:
        """(k,) bool: sections holding skin (some coverage) that miss an arc of more than
        MAX_GAP_DEG of it; False where the slicer did not measure the gaps."""
        if self.largest_gap_deg is None:
            return np.zeros(len(self.heights_mm), dtype=bool)
        return (self.coverage > 0) & (self.largest_gap_deg > MAX_GAP_DEG)

    def with_rows(self, rows: np.ndarray, other: PolarSections, pick: np.ndarray | None = None) -> PolarSections:
        """These sections with their ``rows`` (r,) read from ``other``'s ``pick`` (bool,
        r of them true; all of ``other``'s, r rows, when None; ``other`` on the same
        rays): every per-section array (centre, radii, coverage, the largest gap and where
        it points)."""
        taken_rows = slice(None) if pick is None else pick
        taken = {}
        for name in ("centroids_mm", "radii_mm", "coverage", "largest_gap_deg", "gap_middle_rad"):
            mine, theirs = getattr(self, name), getattr(other, name)
            if mine is not None and theirs is not None:
                mine = mine.copy()
                mine[rows] = theirs[taken_rows]
                taken[name] = mine
        return dataclasses.replace(self, **taken)

    def circumferences(self) -> np.ndarray:
        """(k,) perimeter of each resampled contour (sum of chords, paper section 3.2), mm."""
        return polygon_perimeter(self.radii_mm, self.angles_rad)

    def tape_perimeters(self) -> np.ndarray:
        """(k,) perimeter of the convex hull of each resampled contour (a tape's reading
        of it), mm; NaN for missing sections (:func:`star_hull_perimeters`)."""
        out = np.full(len(self.heights_mm), np.nan)
        valid = self.valid
        out[valid] = star_hull_perimeters(self.radii_mm[valid], self.angles_rad)
        return out

    def mean_radii(self) -> np.ndarray:
        """(k,) mean radius of each contour, mm (``r_k`` of the error index, eq. 4)."""
        return self.radii_mm.mean(axis=1)

    def elongations(self) -> np.ndarray:
        """(k,) elongation of each contour: sqrt of the ratio of the principal second
        moments of its ray end points (1 for a circle; sqrt(a/b) for an a x b ellipse
        seen on equal-angle rays from its centre; NaN for missing sections).
        Dimensionless."""
        a = self.angles_rad
        x = self.radii_mm * np.cos(a)
        y = self.radii_mm * np.sin(a)
        x = x - x.mean(axis=1, keepdims=True)
        y = y - y.mean(axis=1, keepdims=True)
        cxx, cyy, cxy = (x * x).mean(axis=1), (y * y).mean(axis=1), (x * y).mean(axis=1)
        half_trace = (cxx + cyy) / 2
        root = np.sqrt(np.maximum(half_trace**2 - (cxx * cyy - cxy**2), 0.0))
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.sqrt((half_trace + root) / (half_trace - root))


#: a cloud's calf section or feature layer whose own slab cannot be closed is
#: interpolated from the closed calf sections at most this far above and below it, mm:
#: the reach of a sparse cloud's slab (app.geometry.sections.cloud.MAX_HALF_MM), over
#: which a leg's section changes smoothly (girth slope at most ~1 mm per mm)
LAYER_BRIDGE_MM = 10.0


def bridge_sections(layers: PolarSections, sections: PolarSections) -> PolarSections:
    """``layers`` with each missing row linearly interpolated (centroid and radii on the
    shared rays) between the nearest closed rows of ``sections`` below and above it,
    when both lie within :data:`LAYER_BRIDGE_MM`; other rows as they are.  Both (k, a)
    on the same ``a`` rays, heights in mm (``layers`` may be ``sections`` itself)."""
    radii, centres = layers.radii_mm.copy(), layers.centroids_mm.copy()
    closed = np.flatnonzero(sections.valid)
    z = sections.heights_mm[closed]  # rising
    rows = np.flatnonzero(~layers.valid)
    h = layers.heights_mm[rows]
    below = np.searchsorted(z, h, side="right") - 1  # the last closed row at or under each
    above = np.searchsorted(z, h, side="left")  # the first at or over it
    inside = (below >= 0) & (above < len(z))
    lo, hi = closed[np.clip(below, 0, None)[inside]], closed[np.clip(above, None, len(z) - 1)[inside]]
    rows, h = rows[inside], h[inside]
    z_lo, z_hi = sections.heights_mm[lo], sections.heights_mm[hi]
    near = (h - z_lo <= LAYER_BRIDGE_MM) & (z_hi - h <= LAYER_BRIDGE_MM)
    rows, h, lo, hi, z_lo, z_hi = rows[near], h[near], lo[near], hi[near], z_lo[near], z_hi[near]
    span = z_hi - z_lo
    t = np.divide(h - z_lo, span, out=np.zeros_like(h), where=span != 0)[:, None]
    radii[rows] = (1 - t) * sections.radii_mm[lo] + t * sections.radii_mm[hi]
    centres[rows] = (1 - t) * sections.centroids_mm[lo] + t * sections.centroids_mm[hi]
    return dataclasses.replace(layers, radii_mm=radii, centroids_mm=centres)


def largest_gap(filled: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The largest run of empty rays or bins of each row, cyclically: filled (k, b) bool
    over one turn from angle 0 -> its size in degrees (k,) (360 for a row with nothing)
    and the angle of its middle in radians (k,) (NaN for a row without a gap)."""
    k, b = filled.shape
    empty = ~np.tile(filled, 2)
    # run length of empties ending at each position, via the last filled index
    idx = np.broadcast_to(np.arange(2 * b), (k, 2 * b))
    last_filled = np.maximum.accumulate(np.where(empty, -1, idx), axis=1)
    run = np.where(empty, idx - last_filled, 0)
    end = run.argmax(axis=1)
    length = np.minimum(run[np.arange(k), end], b)
    middle = np.where(length > 0, (end - (length - 1) / 2.0) * (2.0 * np.pi / b) % (2.0 * np.pi), np.nan)
    return length * (360.0 / b), middle


def ray_angles(n_angles: int) -> np.ndarray:
    """(n_angles,) equally spaced angles in [0, 2*pi)."""
    return np.arange(n_angles) * (2.0 * np.pi / n_angles)


def polygon_perimeter(radii: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Perimeter of closed polar polygons.

    radii : (..., a) radii at ``angles`` (a,); returns (...,) sum of chord lengths.
    """
    x = radii * np.cos(angles)
    y = radii * np.sin(angles)
    dx = np.roll(x, -1, axis=-1) - x
    dy = np.roll(y, -1, axis=-1) - y
    return np.hypot(dx, dy).sum(axis=-1)


def polygon_centroid(contour: np.ndarray) -> np.ndarray:
    """Area centroid of closed polygons: contour (..., a, 2) -> (..., 2) (shoelace)."""
    x, y = contour[..., 0], contour[..., 1]
    xn, yn = np.roll(x, -1, axis=-1), np.roll(y, -1, axis=-1)
    cross = x * yn - xn * y
    area = cross.sum(axis=-1) / 2.0
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = ((x + xn) * cross).sum(axis=-1) / (6.0 * area)
        cy = ((y + yn) * cross).sum(axis=-1) / (6.0 * area)
    return np.stack([cx, cy], axis=-1)


def star_hull_perimeters(radii: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Perimeter of the convex hull of each star-shaped contour, mm: radii (k, a) > 0 on
    the rays ``angles`` (a,) ascending over one turn from a point inside each contour.

    All sections at once: a vertex that turns inwards (clockwise) between its living
    neighbours lies inside the triangle they make with the centre, so it is not on the
    hull; every such vertex is dropped at once and the test repeated until every living
    vertex turns outwards - the convex hull (the reflex-vertex deletion behind Graham's
    scan and Sklansky's algorithm for star-shaped polygons, run over all sections at
    once; a row's living vertices are kept first and in order, so its neighbours are the
    adjacent entries).  Equal to scipy's ``ConvexHull(ring).area`` (2-D: the perimeter)
    to 1e-9 mm (tests/geometry/test_sections.py) and faster than a ConvexHull per
    section from a handful of sections on (3-7x for 50-300; benchmarks/bench_fit.py):
    a fit measures a thigh's profile of ~200 sections.
    """
    k, a = radii.shape
    if k == 0:
        return np.zeros(0)
    x, y = radii * np.cos(angles), radii * np.sin(angles)
    count = np.full(k, a)  # living vertices of each row, kept first and in order
    scale = 1e-12 * np.maximum(np.nanmax(radii, axis=1), 1.0) ** 2
    rows = np.arange(k)  # the rows still losing vertices: a finished row leaves the loop
    perimeters = np.zeros(k)
    while True:
        j = np.arange(x.shape[1])[None, :]
        living = j < count[:, None]
        before, after = (j - 1) % count[:, None], (j + 1) % count[:, None]
        px, py = np.take_along_axis(x, before, axis=1), np.take_along_axis(y, before, axis=1)
        nx, ny = np.take_along_axis(x, after, axis=1), np.take_along_axis(y, after, axis=1)
        turn = (x - px) * (ny - y) - (y - py) * (nx - x)  # > 0: turns outwards (anticlockwise)
        reflex = living & (turn <= scale[:, None]) & (count[:, None] > 3)
        going = reflex.any(axis=1)
        done = ~going
        perimeters[rows[done]] = np.where(living[done], np.hypot(nx[done] - x[done], ny[done] - y[done]), 0.0).sum(axis=1)
        if not going.any():
            return perimeters
        keep = living[going] & ~reflex[going]
        x, y, scale, rows = x[going], y[going], scale[going], rows[going]
        count = keep.sum(axis=1)
        order = np.argsort(~keep, axis=1, kind="stable")[:, : count.max()]  # the kept first, in order
        x, y = np.take_along_axis(x, order, axis=1), np.take_along_axis(y, order, axis=1)


def plane_pairs(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Expand per-item plane ranges [lo, hi) (each (m,) int) into (item, plane) index
    pairs, each (s,) int: the planes a triangle or an edge crosses, the rays a segment
    spans."""
    count = np.maximum(hi - lo, 0)
    item = np.repeat(np.arange(len(lo)), count)
    start = np.cumsum(count) - count
    plane = lo[item] + (np.arange(item.size) - start[item])
    return item, plane
