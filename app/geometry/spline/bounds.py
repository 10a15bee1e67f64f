"""What a stored calf surface may cost, and what makes it a leg's tube.

Every operation on a record - measurements, comparisons, designs, exports, populations -
evaluates its B-spline surface.  What that allocates and takes is set by three numbers,
so an imported record is refused when any is past its bound (checked before any work;
the error names the limit and the value):

- **the patch cost** ``(nu - p) (nv - q) (p + 1) (q + 1)``: the knot spans of the net
  times the basis products per evaluated point (The NURBS Book A3.5: a point of a
  degree (p, q) patch needs (p + 1)(q + 1) control points).  The volume quadrature
  (:mod:`app.geometry.measures.volume`) evaluates 8 x 4 x 8 Gauss points per span pair, the foot
  points and exports a fixed grid whose cost per point is (p + 1)(q + 1); so time grows
  with this product.  The largest net the service makes itself, an lsq record on the
  40 x 72 grid (cubic: 72 x 37 spans), costs 42,624; :data:`MAX_PATCH_COST` leaves room
  for that and refuses the 253 x 256 quintic net (2.3 million) that took a server down.
- **the height** of the net along the calf axis: measurements tessellate one row per
  0.5 mm and the error grids one per mm.  A whole leg from the sole to the gluteal fold
  is under 1,000 mm (ANSUR II crotch height, largest man: 1,000 mm); :data:`MAX_HEIGHT_MM`.
- **the radius** of the net about the axis: the largest thigh in ANSUR II is ~850 mm
  round (r ~ 135 mm); :data:`MAX_RADIUS_MM` leaves room for control points outside the
  skin.

Memory does not grow with these numbers (the evaluations are chunked: see
:data:`app.geometry.spline.nurbs.EVALUATION_CHUNK_BYTES`, :data:`app.geometry.measures.surface_girths.ROWS_PER_CHUNK`,
:data:`app.geometry.measures.volume.QUADRATURE_CHUNK_POINTS`); the bounds keep the time of any
request on an accepted record to a few seconds.

:func:`check_leg_tube` then refuses surfaces that are not a tube around a leg, whose
girths, volumes and pressures would be NaN or meaningless: a ring thinner than
:data:`MIN_RING_RADIUS_MM`, a tube shorter than :data:`MIN_LENGTH_MM`, a surface whose
height does not rise along v (the volume and the pressure rings cut it by planes
z = h, one crossing per u), or a cross-section that does not wind once around its
centre (a self-overlapping net: the ring's polar angle about its centroid must turn
monotonically through 360 degrees; a leg's cross-section is star-shaped about its
centroid).  Units: mm.
"""

from __future__ import annotations

import numpy as np

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.spline.nurbs import NurbsSurface, evaluate_grid

MAX_PATCH_COST = 50_000
MAX_HEIGHT_MM = 1200.0
MAX_RADIUS_MM = 300.0
MIN_RING_RADIUS_MM = 5.0
MIN_LENGTH_MM = 20.0
#: the tube is sampled on this grid for the shape checks (u around x v along)
SHAPE_SAMPLES_U, SHAPE_SAMPLES_V = 144, 33


def patch_cost(surface: NurbsSurface) -> int:
    """(nu - p) (nv - q) (p + 1) (q + 1): see the module docstring."""
    (nu, nv), p, q = surface.shape, surface.degree_u, surface.degree_v
    return (nu - p) * (nv - q) * (p + 1) * (q + 1)


def _refuse(detail: str, reason: FailureReason = FailureReason.INVALID_RECORD) -> FitFailure:
    return FitFailure(reason, detail)


def check_surface_cost(surface: NurbsSurface) -> None:
    """Refuse (FitFailure ``surface_too_costly``) a net past the bounds of the module
    docstring, before anything is evaluated."""
    (nu, nv), p, q = surface.shape, surface.degree_u, surface.degree_v
    cost = patch_cost(surface)
    if cost > MAX_PATCH_COST:
        raise _refuse(
            f"the control net is {nu} x {nv} at degrees {p} x {q}: its patch cost (nu - p)(nv - q)(p + 1)(q + 1) is "
            f"{cost:,}; this service accepts at most {MAX_PATCH_COST:,} (an lsq record on the 40 x 72 grid costs 42,624)",
            FailureReason.SURFACE_TOO_COSTLY)
    ctrl = surface.control_points
    height = float(np.ptp(ctrl[..., 2]))
    if height > MAX_HEIGHT_MM:
        raise _refuse(f"the control net is {height:.0f} mm tall along the calf axis; a leg's is at most "
                      f"{MAX_HEIGHT_MM:g} mm (sole to gluteal fold)", FailureReason.SURFACE_TOO_COSTLY)
    radius = float(np.hypot(ctrl[..., 0], ctrl[..., 1]).max())
    if radius > MAX_RADIUS_MM:
        raise _refuse(f"control points lie {radius:.0f} mm from the calf axis; a leg's lie within "
                      f"{MAX_RADIUS_MM:g} mm (mm, calf frame: z along the leg)", FailureReason.SURFACE_TOO_COSTLY)


def check_leg_tube(surface: NurbsSurface) -> None:
    """Refuse (``invalid_record``) a surface that is not a tube around a leg (module
    docstring).  Samples :data:`SHAPE_SAMPLES_U` x :data:`SHAPE_SAMPLES_V` points."""
    u0, u1 = surface.domain_u
    v0, v1 = surface.domain_v
    u = u0 + (u1 - u0) * np.arange(SHAPE_SAMPLES_U) / SHAPE_SAMPLES_U
    v = np.linspace(v0, v1, SHAPE_SAMPLES_V)
    with np.errstate(all="ignore"):
        grid = evaluate_grid(surface, u, v)  # (a, b, 3)
    if not np.isfinite(grid).all():
        raise _refuse("the surface evaluates to NaN or infinite points (zero weights or knots)")
    z = grid[..., 2]
    length = float(np.median(z[:, -1] - z[:, 0]))
    if length < MIN_LENGTH_MM:
        raise _refuse(f"the surface is {length:.3g} mm long along the calf axis; a calf record spans at least "
                      f"{MIN_LENGTH_MM:g} mm (B to D is 200-400 mm)")
    rise = np.diff(z, axis=1)
    if (rise <= 0).any():
        row = int(np.argwhere(rise <= 0)[0][1])
        raise _refuse(f"the surface's height does not rise along v (it turns back near v = {v[row]:.3g}): a calf "
                      "record's v runs up the leg from B to D, each ring above the one before")
    centre = grid[..., :2].mean(axis=0)  # (b, 2): the ring centroids
    offset = grid[..., :2] - centre
    radius = np.hypot(offset[..., 0], offset[..., 1])
    if radius.min() < MIN_RING_RADIUS_MM:
        raise _refuse(f"the surface comes within {radius.min():.3g} mm of its axis; a leg's cross-sections are at "
                      f"least {MIN_RING_RADIUS_MM:g} mm in radius (the tube is degenerate)")
    angle = np.unwrap(np.arctan2(offset[..., 1], offset[..., 0]), axis=0)
    steps = np.diff(angle, axis=0)
    direction = np.sign(np.median(steps))
    # the whole turn: the sampled steps plus the closing step from the last sample to the first
    winding = (angle[-1] - angle[0] + steps.mean(axis=0)) / (2 * np.pi)
    if (np.sign(steps) != direction).any() or not np.allclose(np.abs(winding), 1.0, atol=0.05):
        raise _refuse("a cross-section of the surface does not wind once around the leg (its net overlaps itself): "
                      "each ring of a calf record goes once around its centre")
