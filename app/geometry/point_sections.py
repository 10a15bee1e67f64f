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
   centre") and the fit is repeated, so a one-sided hole does not bias the rays.

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

from app.geometry.sections import PolarSections, polygon_centroid, ray_angles

#: harmonics of the polar Fourier fit (a leg section has no detail finer than ~1/12 turn)
HARMONICS = 12
#: bending-energy weight; relative to the data term with all bins filled
SMOOTHING = 0.5
#: largest angular gap without points that a section may have, degrees (see docstring)
MAX_GAP_DEG = 100.0
#: angular bins of the fit (5 degrees, the paper's ray spacing)
N_BINS = 72
#: Tukey biweight tuning constant (95% efficiency at the normal) and robust-sd floor, mm
TUKEY_C = 4.685
MIN_SCALE_MM = 0.5
IRLS_ITERATIONS = 4
#: bounds of the slab half thickness, mm (see :func:`slab_half_thickness`)
MIN_HALF_MM = 1.0
MAX_HALF_MM = 4.0


def _group_median(group: np.ndarray, values: np.ndarray, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
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


def largest_gap_deg(filled: np.ndarray) -> np.ndarray:
    """Largest run of empty bins, cyclically, in degrees: filled (k, b) bool -> (k,)."""
    k, b = filled.shape
    empty = ~np.tile(filled, 2)
    # run length of empties ending at each position, via the last filled index
    idx = np.broadcast_to(np.arange(2 * b), (k, 2 * b))
    last_filled = np.maximum.accumulate(np.where(empty, -1, idx), axis=1)
    run = np.where(empty, idx - last_filled, 0)
    return np.minimum(run.max(axis=1), b) * (360.0 / b)


def _fourier_design(angles: np.ndarray, harmonics: int) -> np.ndarray:
    """(len(angles), 2*harmonics + 1) design matrix [1, cos t, sin t, cos 2t, ...]."""
    order = np.arange(1, harmonics + 1)
    args = angles[:, None] * order[None, :]
    return np.concatenate([np.ones((len(angles), 1)), np.cos(args), np.sin(args)], axis=1)


def robust_polar_fit(bin_radius: np.ndarray, harmonics: int = HARMONICS) -> np.ndarray:
    """Fourier coefficients (k, 2H+1) of r(theta) fitted to bin medians (k, b) (NaN: empty).

    Weighted penalised least squares, reweighted by Tukey's biweight (module docstring).
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
    for _ in range(IRLS_ITERATIONS):
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
    above and below it (a 20 mm slab overstates B's girth by ~3 mm)."""
    density = len(points_z) / max(float(np.ptp(points_z)), 1e-9)  # points per mm of height
    return float(np.clip(2.0 * n_bins / density, MIN_HALF_MM, MAX_HALF_MM))


def slice_points_polar(
    points: np.ndarray,
    heights: np.ndarray,
    n_angles: int = 72,
    half_thickness: float | None = None,
    harmonics: int = HARMONICS,
) -> PolarSections:
    """Polar-resampled sections of a point cloud (see the module docstring).

    points (n, 3) mm in the slicing frame; heights (k,) ascending mm; returns radii on
    ``n_angles`` rays from each section's centre, NaN rows for missing sections.
    """
    heights = np.asarray(heights, dtype=np.float64)
    k = len(heights)
    angles = ray_angles(n_angles)
    if half_thickness is None:
        half_thickness = slab_half_thickness(points[:, 2])
    order = np.argsort(points[:, 2], kind="stable")
    z_sorted = points[order, 2]
    lo = np.searchsorted(z_sorted, heights - half_thickness, side="left")
    hi = np.searchsorted(z_sorted, heights + half_thickness, side="right")
    count = np.maximum(hi - lo, 0)
    plane = np.repeat(np.arange(k), count)
    start = np.cumsum(count) - count
    rank = lo[plane] + (np.arange(plane.size) - start[plane])
    xy = points[order[rank], :2]
    empty = PolarSections(heights, np.full((k, 2), np.nan), np.full((k, n_angles), np.nan), angles, np.zeros(k))
    if plane.size == 0:
        return empty
    centre = np.stack([_group_median(plane, xy[:, i], k)[0] for i in range(2)], axis=1)
    design_out = _fourier_design(angles, harmonics)
    radii = np.full((k, n_angles), np.nan)
    coverage = np.zeros(k)
    ok = np.isfinite(centre).all(axis=1)
    for step in range(3):  # bin, fit, re-centre on the fitted contour's area centroid
        rel = xy - np.nan_to_num(centre)[plane]
        theta = np.arctan2(rel[:, 1], rel[:, 0])
        r = np.hypot(rel[:, 0], rel[:, 1])
        bins = np.floor(theta / (2.0 * np.pi / N_BINS) + 0.5).astype(np.int64) % N_BINS
        bin_radius, bin_count = _group_median(plane * N_BINS + bins, r, k * N_BINS)
        bin_radius = bin_radius.reshape(k, N_BINS)
        filled = bin_count.reshape(k, N_BINS) > 0
        coverage = filled.mean(axis=1)
        ok = np.isfinite(centre).all(axis=1) & (largest_gap_deg(filled) <= MAX_GAP_DEG)
        coefficients = robust_polar_fit(bin_radius, harmonics)
        radii = coefficients @ design_out.T
        ok &= (radii > 0).all(axis=1)
        if step == 2:
            break
        contour = np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=-1)
        shift = polygon_centroid(contour)
        centre = np.where(ok[:, None], np.nan_to_num(centre) + np.nan_to_num(shift), np.nan)
    radii[~ok] = np.nan
    centre[~ok] = np.nan
    return PolarSections(heights, centre, radii, angles, coverage)
