"""Does a point cloud's skin step along a line up the leg?  A cloud captured in parts
while the leg moved.

A scanner that takes one side of the leg and then the other (two views, or a hand-held
sweep down the front and back up the other side) and merges the parts where they meet
gives, when the leg moved in between, a skin cut along a line up the leg: on one side of
the seam the skin lies where it was at the first view, on the other where it was at the
second.  Across the seam the skin steps (the move's part along the skin's normal there)
or opens or overlaps (its part along the skin).  Each part is a smooth leg, the parts
do not overlap, so the skin is not there twice (:mod:`app.geometry.scan.skin_layers` sees
one layer), and the tape - the convex hull of the section - bridges the step and the gap
or misses the overlap: generated legs whose two halves were captured 2-6 mm apart read
their girths 3-11 mm off, in 18 of 20 scans with no warning (benchmarks/motion.py,
``cloud_halves``).  :func:`skin_seam` looks for the step.

Method (a discontinuity of the section's radius, followed up the leg):

1. the points between two heights in slabs :data:`SLAB_MM` thick, each read in polar
   coordinates about its slab's median centre and binned every :data:`BIN_DEG`;
2. at every bin edge of every slab, the skin's radius is extrapolated to the edge from
   each side: a least-squares fit of ``r = a + b u + c u^2 + e z`` to the points within
   :data:`WINDOW_BINS` bins on that side (u the angle from the edge, z the height in the
   slab; the quadratic takes up the section's curvature, so that a ridge - a kink, as
   the tibial crest is - leaves both sides meeting at its apex).  The jump is the two
   sides' difference at the edge, its standard error the two intercepts' (the residuals'
   variance times the normal matrix's inverse);
3. a bin edge steps where the jump is at least :data:`STEP_MM`, :data:`SIGNIFICANCE`
   standard errors and :data:`JUMP_SCALES` times the scan's own jumps' spread (a robust
   standard deviation of the jumps at every edge of the calf); the seam is the path up
   the slabs, one edge per slab moving at most :data:`DRIFT_BINS` from slab to slab (a
   cut plane's trace drifts round a tapered, bent leg), that passes the most stepping
   edges (dynamic programming, as Viterbi's
   algorithm finds the best path through a lattice).  Its ``share`` is the stepping
   edges it passes over the slabs measured.

A rigid move of one part steps along the whole seam; the leg's own shape and a
scanner's noise do not, so the share separates them (measured on the motion benchmark's
clouds, generated and real legs; the numbers are :data:`SEAM_SHARE`'s).  Not caught: a
part that moved into the other along the seam, the move mostly along the skin there -
the parts then overlap over the move's width and the skin bends instead of stepping (the
leg reads narrower by up to twice the move); under about 1 mm of noise, a part moved
away from the other (a gap of the move's width at the seam, which a strip the scanner missed
leaves too: a gap is no proof of a move, so it is not looked for); clouds too sparse for
the windows (under about 0.1 points per mm^2), which are not measured; and a mesh.  A
mesh was read on points drawn by area on its calf's triangles (0.5 per mm^2) and
measured on benchmarks/skin_seam.py 8 43 (commit be3c791, reverted): smooth meshes read
at most 0.18 (BodyParts3D's and the Visible Human legs 0-0.12), but a mesh with 0.3-1 mm of
noise on its vertices read 0.90 (7 of 8 said) and a coarse one 0.80-0.95 (8 of 8).
Points drawn on one facet share its vertices' noise and its flatness, so the standard
error, which takes the points as independent, is far too small, and a polyhedron's edges
bend the parabolas by more than STEP_MM: the test's statistics did not hold for a mesh.
Of the meshes with one half moved, 8 of the 12 that fitted were said.  The spread bound
(:data:`JUMP_SCALES`), added after, reads clouds drawn on such facets at 0.10-0.50: a
mesh could be read again with it, once benchmarks/skin_seam.py measures the mesh kinds.

Units: mm.  Frame: the calf frame (z up the leg).  Arrays: points (n, 3).
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np

#: slab thickness and angular bin, mm and degrees.  A moved part's seam runs straight up
#: the leg, so a thicker slab gives each side's fit more points at no cost to the step:
#: on 48 generated halves clouds (0-1 mm of noise) slabs of 16 mm found 30 seams where 8
#: mm found 25, and single clouds' shares stayed as low (at most 0.23 against 0.27)
SLAB_MM = 16.0
BIN_DEG = 2.0
#: bins on each side of an edge that its radius is extrapolated from (16 degrees: 14 mm
#: of a calf 50 mm in radius, 8 mm of an ankle)
WINDOW_BINS = 8
#: a side's fit needs this many points (4 coefficients)
MIN_SIDE_POINTS = 10
#: the degree of the angular polynomial each side is fitted with (module docstring, 2).
#: With straight lines (degree 1) the tibial crest of BodyParts3D's leg, read as four
#: clouds of 80k points, stepped along 69-81% of its calf, as much as a moved half; with
#: parabolas along 12-19%
ANGULAR_DEGREE = 2
#: an edge steps when its jump is at least this many mm and SIGNIFICANCE standard errors
STEP_MM = 0.5
SIGNIFICANCE = 3.0
#: ... and at least this many times the spread of the scan's own jumps (1.4826 times
#: their median absolute deviation over every edge measured: the seam's few edges do not
#: move it).  The standard error takes the points as independent; a scanner's noise is not
#: always so.  Points drawn on a mesh's facets share each facet's flatness and its
#: vertices' noise: 100k drawn on a coarse generated mesh (8-9 mm edges) or on one with
#: 0.3-1 mm of noise on its vertices read seams along 0.48-0.71 of the calf without this
#: bound, 0.10-0.29 with it at 4 (0.19-0.48 at 3); 48 halves clouds: 30 seams found
#: without it, 26 with it
JUMP_SCALES = 4.0
#: the seam's edge moves at most this many bins from one slab to the next (2 degrees per
#: 16 mm: a cut plane through the whole leg's middle drifts round the calf as the calf's
#: centre moves off it, by about 1 degree per 16 mm on the motion benchmark's legs)
DRIFT_BINS = 1
#: a slab is measured when this share of its edges have both sides fitted, and the cloud
#: when this share of its slabs are
MEASURED_SHARE = 0.5
#: the seam is a moved part's when it steps along at least this share of the slabs
#: measured: half the leg's length, where a single cloud's shape and noise line up for a
#: quarter at most.  Measured on the hold-out run benchmarks/skin_seam.py 8 43 (the
#: bounds were set on other legs): 72 single clouds of generated legs (clean, noisy up to
#: 1 mm, stray points, one side 4 times sparser, holes, a floor, a tessellation's
#: vertices, cropped) at most 0.33, BodyParts3D's real leg 0.06-0.12 (its tibial crest),
#: clouds drawn densely on a coarse mesh's facets 0.32 p50 and once 0.50 (said), on a
#: noisy mesh's 0.10 at most; the same legs' clouds with one half moved 2-6 mm 0.45-1.00
#: without noise (7 of 8 said), 0.55-0.95 with 0.5 mm (8 of 8) and 0.00-0.67 with 1 mm
#: (1 of 8: a seam the noise hides, or one that bends instead of stepping)
SEAM_SHARE = 0.5


@dataclass(frozen=True)
class SkinSeam:
    """Where a cloud's skin steps along a line up the leg (module docstring)."""

    share: float  # the stepping edges on the seam over the slabs measured
    step_mm: float  # the median jump where the seam steps (nan without any)
    slabs: int  # slabs measured
    length_mm: float  # the height the slabs cover

    @classmethod
    def from_dict(cls, data) -> SkinSeam | None:
        """The seam as a record's ``fit.skin_seam`` stores it (:meth:`as_dict`), or None
        when ``data`` is not such a dict (a mesh's record, one made before it was kept,
        one imported from elsewhere)."""
        if not isinstance(data, dict):
            return None
        try:
            return cls(float(data["share"]), float(data["step_mm"]), int(data["slabs"]), float(data["length_mm"]))
        except (KeyError, TypeError, ValueError, OverflowError):
            return None

    def as_dict(self) -> dict:
        return {"share": self.share, "step_mm": self.step_mm, "slabs": self.slabs, "length_mm": self.length_mm,
                "moved": self.moved}

    @property
    def moved(self) -> bool:
        return self.share >= SEAM_SHARE

    @property
    def moved_text(self) -> str:
        """The fit's warning, in words."""
        return (f"the cloud's skin steps by about {self.step_mm:.1f} mm along a line up the leg, over "
                f"{self.share:.0%} of the {self.length_mm:.0f} mm measured: the scanner captured the leg in parts "
                "(one side, then the other) and the leg moved in between; a tape across the seam reads the girths "
                "off by up to about twice the move, and the points placed on the girth profile (E, F, G) may move "
                "with them; scan again with the leg still, or take the girths by tape")


def _window_sums(moments: np.ndarray, side: int, shifted: bool = True) -> np.ndarray:
    """The sums over each edge's window on ``side`` (1: the counter-clockwise side's bins
    j ... j + WINDOW_BINS - 1 of edge j, between bins j - 1 and j; -1: the other's) of
    per-bin moments (p, slabs, bins): ``moments[k]`` the sums of u^k w about each bin's
    centre (u in bins), given back about the edge - (u + a)^k expanded binomially, a the
    bin centre's offset from the edge - or, ``shifted`` False, summed as they are."""
    total = np.zeros_like(moments)
    powers = np.arange(len(moments))
    binomial = np.array([[comb(int(k), int(j)) for j in powers] for k in powers], dtype=np.float64)
    for o in range(WINDOW_BINS):
        roll, a = (-o, o + 0.5) if side == 1 else (o + 1, -(o + 0.5))
        rolled = np.roll(moments, roll, axis=2)
        if not shifted:
            total += rolled
            continue
        # T[k, j] = C(k, j) a^(k - j), zero above the diagonal: sum_j T[k, j] moments[j] = sum (u + a)^k w
        shift = np.tril(binomial * float(a) ** np.maximum(powers[:, None] - powers[None, :], 0))
        total += np.einsum("kj,jsb->ksb", shift, rolled)
    return total


def _edge_jumps(points: np.ndarray, low_mm: float, high_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """(slabs, bins) jumps of the radius at each bin edge (mm, the counter-clockwise side
    less the clockwise side, NaN where a side has too few points) and their standard
    errors, over ``points`` (n, 3) between ``low_mm`` and ``high_mm`` (module docstring,
    steps 1-2).  Each side's normal equations are summed from per-bin moments: the
    moments of the angle about the bin's centre, shifted to the edge binomially."""
    z = points[:, 2]
    points = points[(z >= low_mm) & (z < high_mm)]
    slab = ((points[:, 2] - low_mm) // SLAB_MM).astype(np.int64)
    n_slabs, n_bins = int(slab.max()) + 1, int(round(360.0 / BIN_DEG))
    order = np.argsort(slab, kind="stable")
    starts = np.searchsorted(slab[order], np.arange(n_slabs))
    centre = np.full((n_slabs, 2), np.nan)
    filled = np.bincount(slab, minlength=n_slabs) > 0
    centre[filled] = [np.median(part, axis=0) for part in np.split(points[order, :2], starts[1:]) if len(part)]
    offset = points[:, :2] - centre[slab]
    radius = np.hypot(offset[:, 0], offset[:, 1])
    angle = np.mod(np.arctan2(offset[:, 1], offset[:, 0]), 2.0 * np.pi) / np.deg2rad(BIN_DEG)  # in bins
    column = np.minimum(angle.astype(np.int64), n_bins - 1)
    u = angle - column - 0.5  # about the bin's centre, in bins
    height = points[:, 2] - (low_mm + (slab + 0.5) * SLAB_MM)
    cell = slab * n_bins + column
    deg = ANGULAR_DEGREE

    def summed(weights: np.ndarray) -> np.ndarray:
        return np.bincount(cell, weights=weights, minlength=n_slabs * n_bins).reshape(n_slabs, n_bins)

    u_powers = np.stack([summed(u**k) for k in range(2 * deg + 1)])  # (2 deg + 1, slabs, bins)
    u_radius = np.stack([summed(u**k * radius) for k in range(deg + 1)])
    u_height = np.stack([summed(u**k * height) for k in range(deg + 1)])
    plain = np.stack([summed(height * height), summed(height * radius), summed(radius * radius)])
    intercept, variance = {}, {}
    n_basis = deg + 2  # 1, u, ..., u^deg, z
    for side in (1, -1):
        U, UR, UH = (_window_sums(m, side) for m in (u_powers, u_radius, u_height))
        HH, HR, RR = _window_sums(plain, side, shifted=False)
        normal = np.empty((n_slabs, n_bins, n_basis, n_basis))
        rhs = np.empty((n_slabs, n_bins, n_basis))
        for i in range(deg + 1):
            for j in range(deg + 1):
                normal[..., i, j] = U[i + j]
            normal[..., i, -1] = normal[..., -1, i] = UH[i]
            rhs[..., i] = UR[i]
        normal[..., -1, -1], rhs[..., -1] = HH, HR
        count = U[0]
        fitted = count >= MIN_SIDE_POINTS
        normal[~fitted] = np.eye(n_basis)
        rhs[~fitted] = 0.0
        # a ridge of 1e-9 keeps a side whose points all lie in one bin (u constant) invertible
        inverse = np.linalg.inv(normal + 1e-9 * np.eye(n_basis))
        beta = np.einsum("...ij,...j->...i", inverse, rhs)
        residual = np.maximum(RR - np.einsum("...i,...i->...", beta, rhs), 0.0) / np.maximum(count - n_basis, 1.0)
        intercept[side] = np.where(fitted, beta[..., 0], np.nan)
        variance[side] = np.where(fitted, residual * inverse[..., 0, 0], np.nan)
    return intercept[1] - intercept[-1], np.sqrt(variance[1] + variance[-1])


def _most_stepping_path(stepping: np.ndarray) -> tuple[int, np.ndarray]:
    """The most stepping edges (slabs, bins) bool a path up the slabs passes, one edge per
    slab moving at most DRIFT_BINS round (periodic) from slab to slab, and the path
    (slabs,) of bin indices (module docstring, step 3)."""
    n_slabs, n_bins = stepping.shape
    score = stepping[0].astype(np.int64)
    came = np.zeros((n_slabs, n_bins), dtype=np.int64)
    moves = np.arange(-DRIFT_BINS, DRIFT_BINS + 1)
    for k in range(1, n_slabs):
        options = np.stack([np.roll(score, m) for m in moves])  # options[i, j]: the score at bin j - moves[i]
        best = np.argmax(options, axis=0)
        came[k] = moves[best]
        score = options[best, np.arange(n_bins)] + stepping[k]
    path = np.empty(n_slabs, dtype=np.int64)
    path[-1] = int(np.argmax(score))
    for k in range(n_slabs - 1, 0, -1):
        path[k - 1] = (path[k] - came[k, path[k]]) % n_bins
    return int(score.max()), path


def skin_seam(points: np.ndarray, low_mm: float, high_mm: float) -> SkinSeam | None:
    """The seam of ``points`` (n, 3) calf-frame mm between ``low_mm`` and ``high_mm``
    (module docstring); None when fewer than MEASURED_SHARE of the slabs can be measured
    (a sparse cloud, a short stretch)."""
    points = np.asarray(points, dtype=np.float64)
    if high_mm - low_mm < 4 * SLAB_MM or not len(points):
        return None
    jump, error = _edge_jumps(points, low_mm, high_mm)
    measured = np.isfinite(jump).mean(axis=1) >= MEASURED_SHARE
    if measured.mean() < MEASURED_SHARE:
        return None
    finite = jump[np.isfinite(jump)]
    spread = 1.4826 * float(np.median(np.abs(finite - np.median(finite))))
    with np.errstate(invalid="ignore"):
        size = np.abs(jump)
        stepping = ((size >= STEP_MM) & (size >= SIGNIFICANCE * error) & (size >= JUMP_SCALES * spread)
                    & measured[:, None])
    passed, path = _most_stepping_path(stepping)
    on_path = stepping[np.arange(len(path)), path]
    steps = np.abs(jump[np.arange(len(path)), path][on_path])
    return SkinSeam(share=passed / int(measured.sum()), step_mm=float(np.median(steps)) if steps.size else float("nan"),
                    slabs=int(measured.sum()), length_mm=float(high_mm - low_mm))
