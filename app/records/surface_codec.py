"""The record's surfaces in their open-standard JSON form (The NURBS Book's data: degrees,
knot vectors, control points, weights; u periodic and written unwrapped, see
:mod:`app.geometry.spline.nurbs`), validated on the way in: finite numbers, shapes, the
knot vectors' contract, the cost bounds (:mod:`app.geometry.spline.bounds`) and a tube
closed around the leg.  The calf's ``surface`` and the leg model's
(``leg_model.surface``) both pass through here.  Units: mm, calf frame.
"""

from __future__ import annotations

import numpy as np

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.spline.bounds import check_surface_cost
from app.geometry.spline.nurbs import NurbsSurface, evaluate_grid

#: bounds of an importable record: a calf in its own frame (B at the origin, z along
#: the leg) lies within a few hundred mm of the origin; these leave room for a whole
#: leg and refuse numbers that would make every export and measurement run away
MAX_CONTROL_MM = 2000.0
MAX_NET = 256
#: the surface must close around the leg to this tolerance (mm)
CLOSURE_TOL_MM = 1e-3


def surface_document(s: NurbsSurface) -> dict:
    """The JSON form of a surface."""
    return {"degree_u": s.degree_u, "degree_v": s.degree_v, "knots_u": s.knots_u.tolist(), "knots_v": s.knots_v.tolist(),
            "control_points": s.control_points.tolist(), "weights": s.weights.tolist(), "periodic_u": bool(s.periodic_u)}


def parse_surface(surf: dict) -> NurbsSurface:
    """A validated surface from its JSON form; FitFailure INVALID_RECORD naming the problem."""
    try:
        p, q = int(surf["degree_u"]), int(surf["degree_v"])
    except (KeyError, TypeError, ValueError) as exc:
        raise invalid_record("surface.degree_u and surface.degree_v must be integers") from exc
    if not (1 <= p <= 5 and 1 <= q <= 5):
        raise invalid_record("degrees must be between 1 and 5")
    ctrl = finite_array(surf.get("control_points"), "surface.control_points", 3)
    weights = finite_array(surf.get("weights"), "surface.weights", 2)
    knots_u = finite_array(surf.get("knots_u"), "surface.knots_u", 1)
    knots_v = finite_array(surf.get("knots_v"), "surface.knots_v", 1)
    nu, nv, dim = ctrl.shape
    if dim != 3:
        raise invalid_record("control points must have 3 coordinates")
    if nu > MAX_NET or nv > MAX_NET:
        raise invalid_record(f"the control net is {nu} x {nv}; at most {MAX_NET} x {MAX_NET} is accepted")
    if np.abs(ctrl).max() > MAX_CONTROL_MM:
        raise invalid_record(
            f"control points reach {np.abs(ctrl).max():.3g} mm from the calf frame's origin; a calf record's lie "
            f"within {MAX_CONTROL_MM:g} mm (mm, in the calf frame: B at the origin, z along the leg)")
    if nu <= p or nv <= q:
        raise invalid_record(f"need more than degree control points in each direction, got {nu} x {nv}")
    if weights.shape != (nu, nv):
        raise invalid_record(f"weights must be {nu} x {nv} like the control net, got {weights.shape}")
    if (weights <= 0).any():
        raise invalid_record("weights must be positive")
    for name, knots, n, deg in (("knots_u", knots_u, nu, p), ("knots_v", knots_v, nv, q)):
        if len(knots) != n + deg + 1:
            raise invalid_record(f"surface.{name} must have {n + deg + 1} entries (n + degree + 1), got {len(knots)}")
        if np.any(np.diff(knots) < 0):
            raise invalid_record(f"surface.{name} must be non-decreasing")
        if knots[n] <= knots[deg]:
            raise invalid_record(f"surface.{name} has an empty domain")
    periodic = bool(surf.get("periodic_u", False))
    if periodic and not np.allclose(ctrl[:p], ctrl[nu - p :], atol=1e-6 * max(1.0, float(np.abs(ctrl).max()))):
        raise invalid_record("periodic_u is set but the first degree_u control columns do not repeat at the end")
    try:  # the basis contract: u periodic or clamped, v clamped, no break inside
        surface = NurbsSurface(p, q, knots_u, knots_v, ctrl, weights, periodic)
    except ValueError as broken:
        raise invalid_record(f"surface: {broken}") from None
    check_surface_cost(surface)  # before anything is evaluated
    check_closed_around(surface)
    return surface


def invalid_record(detail: str) -> FitFailure:
    return FitFailure(FailureReason.INVALID_RECORD, detail)


def finite_array(value, name: str, ndim: int) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise invalid_record(f"{name} must be an array of numbers") from exc
    if array.ndim != ndim:
        raise invalid_record(f"{name} must be {ndim}-dimensional, got shape {array.shape}")
    if not np.isfinite(array).all():
        raise invalid_record(f"{name} contains NaN or infinite values")
    return array


def check_closed_around(surface: NurbsSurface) -> None:
    """The surface contract: a tube closed around the leg (u), whether written periodic
    (``periodic_u``, repeated control columns) or clamped with equal first and last
    columns.  The exports, girths and pressure maps join u's two ends; an open sheet
    would get a seam across the leg.  Checked where it matters: the curves u = start
    and u = end at 33 heights must coincide within :data:`CLOSURE_TOL_MM`."""
    (nu, nv), p, q = surface.shape, surface.degree_u, surface.degree_v
    ends = np.array([surface.knots_u[p], surface.knots_u[nu]])
    v = np.linspace(surface.knots_v[q], surface.knots_v[nv], 33)
    with np.errstate(all="ignore"):
        points = evaluate_grid(surface, ends, v)
    gap = float(np.linalg.norm(points[0] - points[1], axis=-1).max())
    if not np.isfinite(gap) or gap > CLOSURE_TOL_MM:
        raise invalid_record(
            f"the surface is not closed around the leg: its two u ends are up to {gap:.3g} mm apart. A calf record "
            "is a tube: periodic_u with the first degree_u control columns repeated at the end, or a clamped u "
            "whose first and last control columns coincide")
