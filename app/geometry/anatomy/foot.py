"""The foot's points of the order form, measured from the scan as a tape would: the foot
length, cA (the forefoot girth over the metatarsal heads) and cY (the heel-instep
diagonal), RAL-GZ 387's measuring points below B.

Frame: the calf frame (mm; z up the leg from B = 0, y anterior, x the subject's right),
``sole_mm`` the z of the sole.  Arrays: points (n, 3), faces (f, 3) or None.

- **Foot axis and length.**  The footprint (points within FOOTPRINT_MM of the sole) gives
  the foot's long axis as its first principal direction in the horizontal plane, pointed
  forward (+y); the foot length is the footprint-and-foot extent along that axis, heel to
  the tip of the longest toe (ISO 7250-1 5.3.1: foot length parallel to the foot axis),
  from the third-lowest and third-highest projection (robust to two stragglers the
  clean-up left; on a 2 mm scan this moves a tip by under 1 mm).
- **cA, the ball girth.**  ANSUR II's ball-of-foot length (heel to the first metatarsal
  head) is 0.740 +- 0.014 of the foot length (6,068 subjects, tests/data/ansur2), and the
  fifth metatarsal head lies about 0.1 of the foot length behind the first; the ball
  girth is where the forefoot is largest over them: the largest tape girth (convex hull
  of the section, :func:`app.geometry.sections.tape_girths`) in vertical planes
  perpendicular to the foot axis from 0.62 to 0.78 of the foot length, every 2 mm.
- **cY, the heel-instep diagonal.**  The tape passes under the back of the heel and over
  the instep (the front of the ankle fold).  Its planes contain the foot's transverse
  axis and pass through the heel's posterior-inferior point (the foot point furthest
  back-and-down, at 45 degrees in the sagittal plane); tilted 30-65 degrees from the floor,
  the loop is the smallest of them (the tape tightens to the shortest loop), as the
  shoemakers' long heel girth is taken.
- **A foot that is not all there** is not measured: a footprint shorter than 150 mm, or
  an end that does not taper (the section 6 mm inside the toe or heel end is more than
  0.7 of the ball girth: a crop, not a toe) says why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.sections import tape_girths

#: points this close to the sole (mm) are its footprint
FOOTPRINT_MM = 25.0
#: shortest foot the rules are for (a child's foot is ~150 mm), mm
MIN_FOOT_MM = 150.0
#: the ball girth's window, as fractions of the foot length from the heel (module docstring)
BALL_WINDOW = (0.62, 0.78)
BALL_STEP_MM = 2.0
#: the heel-instep planes' tilt from the floor, degrees, and their step
INSTEP_TILT_DEG = (30.0, 65.0)
INSTEP_STEP_DEG = 2.5
#: an end whose section 6 mm inside is above this share of the ball girth was cut, not tapered
END_TAPER_SHARE = 0.7
END_INSET_MM = 6.0
#: the heel-instep loop rises to the front of the ankle, above B on most legs: its planes
#: see the scan below this height (mm above B; the loop tops out 20-50 mm above B)
INSTEP_TOP_MM = 80.0


@dataclass(frozen=True)
class FootPoint:
    """One measured point: ``value_mm`` (None, with the ``reason``, when not measured) and
    where on the foot, calf frame mm (the centre of the tape's loop, (3,))."""

    name: str
    value_mm: float | None
    at_mm: tuple[float, float, float] | None = None
    reason: str | None = None

    def as_dict(self) -> dict:
        return {"value_mm": self.value_mm, "at_mm": None if self.at_mm is None else list(self.at_mm), "reason": self.reason}


@dataclass(frozen=True)
class FootMeasures:
    foot_length: FootPoint
    ball_girth: FootPoint  # cA
    heel_instep_girth: FootPoint  # cY

    def as_dict(self) -> dict:
        return {"foot_length": self.foot_length.as_dict(), "cA": self.ball_girth.as_dict(), "cY": self.heel_instep_girth.as_dict()}


def _xyz(point: np.ndarray) -> tuple[float, float, float]:
    return float(point[0]), float(point[1]), float(point[2])


def _not_measured(reason: str) -> FootMeasures:
    return FootMeasures(FootPoint("foot_length", None, reason=reason), FootPoint("cA", None, reason=reason),
                        FootPoint("cY", None, reason=reason))


def _below(points: np.ndarray, faces: np.ndarray | None, z_max: float) -> tuple[np.ndarray, np.ndarray | None]:
    """The part of the scan below ``z_max`` (a mesh keeps the faces wholly below)."""
    if faces is None or not len(faces):
        return points[points[:, 2] < z_max], None
    keep = (points[faces, 2] < z_max).all(axis=1)
    used = np.unique(faces[keep])
    index = np.full(len(points), -1)
    index[used] = np.arange(len(used))
    return points[used], index[faces[keep]]


def _plane_girths(points: np.ndarray, faces: np.ndarray | None, origin: np.ndarray, basis: np.ndarray,
                  offsets: np.ndarray) -> np.ndarray:
    """Tape girths in the planes {p : (p - origin) . basis[2] = offset}, basis (3, 3)
    orthonormal rows (the third the planes' normal); (k,) mm, NaN where no section."""
    return tape_girths((points - origin) @ basis.T, faces, offsets)


def foot_measures(points: np.ndarray, faces: np.ndarray | None, sole_mm: float | None) -> FootMeasures:
    """The foot length, cA and cY of the module docstring (mm), or why not."""
    if sole_mm is None:
        return _not_measured("the foot is not in the scan")
    below_b, below_faces = _below(points, faces, 0.5 * sole_mm)  # the foot: below halfway from the sole to B
    footprint = below_b[below_b[:, 2] < sole_mm + FOOTPRINT_MM]
    if len(footprint) < 50:
        return _not_measured("the scan has too few points near the sole to find the foot")
    xy = footprint[:, :2] - footprint[:, :2].mean(axis=0)
    _, _, vt = np.linalg.svd(xy, full_matrices=False)
    axis2 = vt[0] if vt[0][1] >= 0 else -vt[0]
    axis = np.array([axis2[0], axis2[1], 0.0])
    across = np.cross([0.0, 0.0, 1.0], axis)
    along = below_b @ axis
    ordered = np.sort(along)
    heel_t, toe_t = ordered[2], ordered[-3]
    length = float(toe_t - heel_t)
    if length < MIN_FOOT_MM:
        return _not_measured(f"the foot in the scan is {length:.0f} mm long, shorter than any foot "
                             f"({MIN_FOOT_MM:.0f} mm): it is cut")
    centre_x = float(np.median(below_b @ across))
    sole_point = np.array([0.0, 0.0, sole_mm]) + centre_x * across
    # cA: vertical planes across the foot axis (basis: across, up, axis)
    basis = np.array([across, [0.0, 0.0, 1.0], axis])
    origin = sole_point - (sole_point @ axis) * axis
    lo, hi = heel_t + BALL_WINDOW[0] * length, heel_t + BALL_WINDOW[1] * length
    offsets = np.arange(lo, hi + 1e-9, BALL_STEP_MM)
    window = _plane_girths(below_b, below_faces, origin, basis, offsets)
    ends = _plane_girths(below_b, below_faces, origin, basis, np.array([heel_t + END_INSET_MM, toe_t - END_INSET_MM]))
    foot_length = FootPoint("foot_length", length, _xyz(origin + (heel_t + toe_t) / 2 * axis))
    if not np.isfinite(window).any():
        reason = "the forefoot has no closed section over the metatarsal heads (a hole or a crop)"
        return FootMeasures(foot_length, FootPoint("cA", None, reason=reason), FootPoint("cY", None, reason=reason))
    best = int(np.nanargmax(window))
    ball = float(window[best])
    cut = [name for name, g in zip(("heel", "toes"), ends) if np.isfinite(g) and g > END_TAPER_SHARE * ball]
    if cut:
        reason = f"the {' and '.join(cut)} end in a section {max(ends):.0f} mm round, not a taper: the foot is cut"
        return FootMeasures(FootPoint("foot_length", None, reason=reason), FootPoint("cA", None, reason=reason),
                            FootPoint("cY", None, reason=reason))
    ball_at = origin + offsets[best] * axis
    ball_point = FootPoint("cA", ball, _xyz(ball_at + (sole_mm + 25.0 - ball_at[2]) * basis[1]))
    instep, instep_faces = _below(points, faces, INSTEP_TOP_MM)
    return FootMeasures(foot_length, ball_point, _heel_instep(instep, instep_faces, axis, across))


def _heel_instep(points: np.ndarray, faces: np.ndarray | None, axis: np.ndarray, across: np.ndarray) -> FootPoint:
    """cY: the smallest loop through the heel's posterior-inferior point over the instep,
    planes tilted INSTEP_TILT_DEG from the floor about the transverse axis."""
    up = np.array([0.0, 0.0, 1.0])
    back_down = -(axis + up) / np.sqrt(2.0)
    heel = points[int(np.argmax(points @ back_down))]
    tilts = np.radians(np.arange(INSTEP_TILT_DEG[0], INSTEP_TILT_DEG[1] + 1e-9, INSTEP_STEP_DEG))
    girths = np.full(len(tilts), np.nan)
    for i, tilt in enumerate(tilts):  # one plane per tilt: a handful of planes, each vectorised
        in_plane = np.cos(tilt) * axis + np.sin(tilt) * up
        normal = np.cross(across, in_plane)
        girths[i] = _plane_girths(points, faces, heel, np.array([across, in_plane, normal]), np.array([0.0]))[0]
    if not np.isfinite(girths).any():
        return FootPoint("cY", None, reason="no closed loop around the heel and the instep (a hole or a crop)")
    best = int(np.nanargmin(girths))
    in_plane = np.cos(tilts[best]) * axis + np.sin(tilts[best]) * up
    return FootPoint("cY", float(girths[best]), _xyz(heel + 60.0 * in_plane))
