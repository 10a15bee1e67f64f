"""Cross-sections of a point cloud: a robust polar curve fit per slab (paper section 2.1).

The paper fits every cross-section "in the polar coordinate system" to get the explicit
shape of the contour.  For a point cloud a plane holds no points, so each plane
``z = h_k`` takes the slab of points within ``half_thickness`` of it, and:

1. the points are binned by angle about a provisional centre (the slab's coordinate-wise
   median, which stray points do not drag); each bin keeps the *median* radius of its
   points, so a side sampled 4x sparser weighs as much as a dense one and a bin may hold
   up to half outliers;
2. a smooth periodic ``r(theta)`` - a truncated Fourier series of
   :data:`HARMONICS` harmonics with a bending-energy penalty ~ k^4 - is fitted to the bin
   medians by iteratively reweighted least squares with Tukey's biweight
   (c = 4.685 robust sd, the sd from the median absolute residual), so ghost points and
   streaks a few mm to cm off the skin get weight 0; the penalty carries the contour
   across angular gaps (holes) where no bin has data;
3. the centre moves to the area centroid of the fitted contour (the paper's "weight
   centre") and the fit is repeated, so a one-sided hole does not bias the rays.  The
   first fit only places the centre (the slab's median lies 5-40 mm off the centroid
   of a section sampled unevenly), so it takes :data:`CENTRING_IRLS_ITERATIONS` rounds;
   a section is refitted again only while its centre still moves more than
   :data:`RECENTRE_TOLERANCE_MM` (on the corpus the second move is 0.04-0.3 mm).

``coverage`` is the fraction of angular bins holding points; a section whose largest
angular gap exceeds :data:`MAX_GAP_DEG` is missing (NaN): the fit would be guessing.
Why 100 degrees: a 40 mm hole spans 40 / r radians, 76 degrees at a 30 mm ankle radius
(the smallest ANSUR ankle girth, 156 mm, has r = 25 mm: 92 degrees); a section seen over
less than 260 degrees is not a scan of that section.

Normals are not needed.  Units: mm.  Arrays: points (n, 3) in the slicing frame,
heights (k,), radii (k, a).
"""

from __future__ import annotations

import numpy as np

from app.geometry.sections.polar import MAX_GAP_DEG, PolarSections, largest_gap, polygon_centroid, ray_angles

#: harmonics of the polar Fourier fit (a leg section has no detail finer than ~1/12 turn)
HARMONICS = 12
#: bending-energy weight; relative to the data term with all bins filled
SMOOTHING = 0.5
#: angular bins of the fit (5 degrees, the paper's ray spacing)
N_BINS = 72
#: Tukey biweight tuning constant (95% efficiency at the normal) and robust-sd floor, mm
TUKEY_C = 4.685
MIN_SCALE_MM = 0.5
IRLS_ITERATIONS = 4
#: IRLS rounds of the first, centring fit: its contour only gives the area centroid (an
#: integral of the contour, which a residual outlier bin moves by a fraction of a mm)
CENTRING_IRLS_ITERATIONS = 2
#: a section whose ray origin would move less than this is final, mm: the rays then turn
#: by under 0.6 degrees at a 50 mm radius (an eighth of the 5-degree ray spacing) and the
#: girth, which does not depend on the origin, not at all
RECENTRE_TOLERANCE_MM = 0.5
MAX_RECENTRES = 3
#: the provisional centre (coordinate-wise median) is the median of every this-many-th
#: point of a slab: it only has to fall inside the section
CENTRE_STRIDE = 4
#: bounds of the slab half thickness, mm (see :func:`slab_half_thickness`)
MIN_HALF_MM = 1.0
MAX_HALF_MM = 10.0
#: the density a cloud needs, points per mm of the leg's height: a section is closed when
#: no gap between its points' angles exceeds 100 degrees (MAX_GAP_DEG); n points at
#: random angles leave such a gap with probability ~ n (1 - 100/360)^(n-1): 4% for n = 20,
#: 30% for n = 12.  The thickest slab is 20 mm (MAX_HALF_MM),
#: so 20 points per slab is 1 point per mm (checked on the vertices of a real body: 7k
#: points, ~1.3 per mm of a leg, fit within 5 mm of the mesh; 4k, ~0.8 per mm, do not)
MIN_CLOUD_POINTS_PER_MM = 1.0
#: a slab filling fewer of the 72 angular bins than this is measured again thicker, by
#: this factor a step (see :func:`slice_points_polar`); a scanner's dense cloud fills
#: 95-100% of them at its first thickness
WIDEN_BELOW_COVERAGE = 0.9
WIDEN_FACTOR = 1.5


def group_median(group: np.ndarray, values: np.ndarray, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """Median of ``values`` (m,) within each ``group`` (m,) label < n_groups; and counts.

    One argsort of the float key ``group * span + (value - min)`` (span > the values'
    range, so the key orders by group, then value; exact to ~1e-8 of the range for up
    to 10^7 groups) - ten times faster than ``np.lexsort`` on two keys - then the
    middle element(s) of every run.  Empty groups give NaN.
    """
    low = float(values.min()) if values.size else 0.0
    span = (float(values.max()) - low if values.size else 0.0) + 1.0
    order = np.argsort(group * span + (values - low))
    g, v = group[order], values[order]
    count = np.bincount(g, minlength=n_groups)
    start = np.cumsum(count) - count
    median = np.full(n_groups, np.nan)
    has = count > 0
    lo = start[has] + (count[has] - 1) // 2
    hi = start[has] + count[has] // 2
    median[has] = 0.5 * (v[lo] + v[hi])
    return median, count


def _row_nanmedian(values: np.ndarray) -> np.ndarray:
    """Median of each row of ``values`` (k, b) over its finite entries (NaN for a row
    with none): one sort, NaN last, then the middle of the finite run - several times
    faster than ``np.nanmedian`` along an axis."""
    ordered = np.sort(values, axis=1)
    n = np.isfinite(values).sum(axis=1)
    rows = np.arange(len(values))
    lo, hi = np.maximum((n - 1) // 2, 0), np.maximum(n // 2, 0)
    with np.errstate(invalid="ignore"):
        return np.where(n > 0, 0.5 * (ordered[rows, lo] + ordered[rows, hi]), np.nan)


def _fourier_design(angles: np.ndarray, harmonics: int) -> np.ndarray:
    """(len(angles), 2*harmonics + 1) design matrix [1, cos t, sin t, cos 2t, ...]."""
    order = np.arange(1, harmonics + 1)
    args = angles[:, None] * order[None, :]
    return np.concatenate([np.ones((len(angles), 1)), np.cos(args), np.sin(args)], axis=1)


def robust_polar_fit(bin_radius: np.ndarray, harmonics: int = HARMONICS,
                     iterations: int = IRLS_ITERATIONS) -> np.ndarray:
    """Fourier coefficients (k, 2H+1) of r(theta) fitted to bin medians (k, b) (NaN: empty).

    Weighted penalised least squares, reweighted by Tukey's biweight (module docstring),
    ``iterations`` rounds.
    """
    k, b = bin_radius.shape
    design = _fourier_design(ray_angles(b), harmonics)
    has = np.isfinite(bin_radius)
    target = np.where(has, bin_radius, 0.0)
    order = np.concatenate([[0.0], np.arange(1, harmonics + 1), np.arange(1, harmonics + 1)])
    ridge = np.diag(SMOOTHING * (order / harmonics) ** 4 + 1e-9) * b
    weight = has.astype(np.float64)
    n = design.shape[1]
    outer = (design[:, :, None] * design[:, None, :]).reshape(b, n * n)  # (b, n*n)
    coefficients = np.zeros((k, n))
    for _ in range(iterations):
        normal = (weight @ outer).reshape(k, n, n) + ridge[None]  # one BLAS product
        rhs = (weight * target) @ design
        coefficients = np.linalg.solve(normal, rhs[..., None])[..., 0]
        residual = np.where(has, target - coefficients @ design.T, np.nan)
        # (a section with no point at all keeps the floor scale)
        scale = np.maximum(1.4826 * np.nan_to_num(_row_nanmedian(np.abs(residual))), MIN_SCALE_MM)
        u = np.nan_to_num(residual / (TUKEY_C * scale[:, None]), nan=2.0)
        weight = np.where(np.abs(u) < 1.0, (1.0 - u**2) ** 2, 0.0) * has
    return coefficients


def slab_half_thickness(points_z: np.ndarray, n_bins: int = N_BINS) -> float:
    """Half thickness (mm) of the slabs: thick enough that a slab holds ~4 points per
    angular bin on average, at least :data:`MIN_HALF_MM` (the paper's scanner samples
    every 1 mm), at most :data:`MAX_HALF_MM`.

    It does not grow with the spacing of the planes: a slab is a measurement of the
    section at its plane, and a thick slab at the ankle minimum B reads the wider leg
    above and below it (a 20 mm slab overstates B's girth by ~3 mm).  A cloud as dense as
    a scanner's (40-120k points over a leg: 45-130 points per mm of height) gets 1-3.3
    mm; the 10 mm cap is reached only by sparse clouds (the vertices of a 10-30k vertex
    body scan: 3-10 points per mm of a leg), whose tape girths the fit reads on their
    neighbour graph instead, and says so
    (app.geometry.fit.sparse_clouds.SPARSE_CLOUD_POINTS_PER_MM)."""
    density = len(points_z) / max(float(np.ptp(points_z)), 1e-9)  # points per mm of height
    return float(np.clip(2.0 * n_bins / density, MIN_HALF_MM, MAX_HALF_MM))


def slice_points_polar(
    points: np.ndarray,
    heights: np.ndarray,
    n_angles: int = 72,
    half_thickness: float | None = None,
    harmonics: int = HARMONICS,
    widen: bool = True,
) -> PolarSections:
    """Polar-resampled sections of a point cloud (see the module docstring).

    points (n, 3) mm in the slicing frame; heights (k,) ascending mm; returns radii on
    ``n_angles`` rays from each section's centre, NaN rows for missing sections.

    A slab whose points fill fewer than :data:`WIDEN_BELOW_COVERAGE` of the angular bins
    is measured again :data:`WIDEN_FACTOR` times thicker, up to :data:`MAX_HALF_MM`
    (and kept when that fills more bins): the vertices of a mesh exported as a cloud lie
    on the mesh's rings, 1.5-3 mm apart along a ring but up to several mm between rings
    that are tilted to the slicing planes, so a slab as thin as the mean density allows
    catches arcs of a ring, not the ring.  Only the slabs that need it grow: the ankle's
    girth, which a thick slab overstates, stays measured on the thinnest slab that sees
    its whole ring.  ``widen=False`` keeps the given thickness (points that lie in their
    planes, a mesh's section ends, gain nothing from a thicker slab).
    """
    heights = np.asarray(heights, dtype=np.float64)
    if half_thickness is None:
        half_thickness = slab_half_thickness(points[:, 2])
    order = np.argsort(points[:, 2], kind="stable")  # once, for every thickness
    ordered = (order, points[order, 2])
    sections = _slice_slabs(points, ordered, heights, n_angles, half_thickness, harmonics)
    half = half_thickness
    while widen and half < MAX_HALF_MM:
        thin = np.flatnonzero(sections.coverage < WIDEN_BELOW_COVERAGE)
        if not thin.size:
            break
        half = min(half * WIDEN_FACTOR, MAX_HALF_MM)
        wider = _slice_slabs(points, ordered, heights[thin], n_angles, half, harmonics)
        better = (wider.coverage > sections.coverage[thin]) & np.isfinite(wider.radii_mm).all(axis=1)
        if not better.any():
            continue
        sections = sections.with_rows(thin[better], wider, better)
    return sections


def _slice_slabs(points: np.ndarray, ordered: tuple[np.ndarray, np.ndarray], heights: np.ndarray, n_angles: int,
                 half_thickness: float, harmonics: int) -> PolarSections:
    """The robust polar fit of every slab of ``half_thickness`` (mm) around ``heights``
    (k,) at once (see :func:`slice_points_polar`); ``ordered``: the points' order along
    z (n,) and their sorted z (n,)."""
    k = len(heights)
    angles = ray_angles(n_angles)
    order, z_sorted = ordered
    lo = np.searchsorted(z_sorted, heights - half_thickness, side="left")
    hi = np.searchsorted(z_sorted, heights + half_thickness, side="right")
    count = np.maximum(hi - lo, 0)
    plane = np.repeat(np.arange(k), count)
    start = np.cumsum(count) - count
    within = np.arange(plane.size) - start[plane]  # each point's place in its slab
    rank = lo[plane] + within
    xy = points[order[rank], :2]
    empty = PolarSections(heights, np.full((k, 2), np.nan), np.full((k, n_angles), np.nan), angles, np.zeros(k),
                          np.full(k, 360.0), np.full(k, np.nan))
    if plane.size == 0:
        return empty
    # every CENTRE_STRIDE-th point of each slab, counted from the slab's own first point:
    # a section's centre (and so its girth) then depends on its own slab only, not on
    # which other heights are read in the same call
    sub = within % CENTRE_STRIDE == 0
    centre = np.stack([group_median(plane[sub], xy[sub, i], k)[0] for i in range(2)], axis=1)
    design_out = _fourier_design(angles, harmonics)
    radii = np.full((k, n_angles), np.nan)
    coverage = np.zeros(k)
    gap, middle = np.full(k, 360.0), np.full(k, np.nan)
    ok = np.isfinite(centre).all(axis=1)
    todo = np.flatnonzero(ok)  # sections whose ray origin is still moving
    for step in range(MAX_RECENTRES + 1):  # bin, fit, re-centre on the fitted contour's area centroid
        index = np.full(k, -1)
        index[todo] = np.arange(len(todo))
        mine = index[plane] >= 0
        group = index[plane[mine]]
        rel = xy[mine] - centre[plane[mine]]
        theta = np.arctan2(rel[:, 1], rel[:, 0])
        r = np.hypot(rel[:, 0], rel[:, 1])
        bins = np.floor(theta / (2.0 * np.pi / N_BINS) + 0.5).astype(np.int64) % N_BINS
        bin_radius, bin_count = group_median(group * N_BINS + bins, r, len(todo) * N_BINS)
        filled = bin_count.reshape(len(todo), N_BINS) > 0
        coverage[todo] = filled.mean(axis=1)
        gap[todo], middle[todo] = largest_gap(filled)
        coefficients = robust_polar_fit(bin_radius.reshape(len(todo), N_BINS), harmonics,
                                        CENTRING_IRLS_ITERATIONS if step == 0 else IRLS_ITERATIONS)
        radii[todo] = coefficients @ design_out.T
        ok[todo] = (gap[todo] <= MAX_GAP_DEG) & (radii[todo] > 0).all(axis=1)
        if step == MAX_RECENTRES:
            break
        contour = np.stack([radii[todo] * np.cos(angles), radii[todo] * np.sin(angles)], axis=-1)
        shift = np.nan_to_num(polygon_centroid(contour))
        moving = ok[todo] & ((np.hypot(shift[:, 0], shift[:, 1]) > RECENTRE_TOLERANCE_MM) | (step == 0))
        centre[todo[moving]] += shift[moving]
        todo = todo[moving]
        if todo.size == 0:
            break
    radii[~ok] = np.nan
    centre[~ok] = np.nan
    return PolarSections(heights, centre, radii, angles, coverage, gap, middle)
