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
- **cY, the heel-instep diagonal.**  The tape passes round the back of the heel and over
  the front of the ankle (ANSUR II's heel-ankle circumference; RAL-GZ 387's "Fersen-Rist-
  Umfang").  Its plane contains the foot's transverse axis and passes through the heel's
  posterior-inferior point (the foot point furthest back-and-down, at 45 degrees in the
  sagittal plane) and the front of the ankle: on the anterior profile of the foot's
  mid-plane, the deepest point of the concave corner where the dorsum meets the shank
  (the profile point furthest behind the chord from the toe tip to the shank at B).
- **A foot that is not all there** is not measured: a footprint shorter than 150 mm, or
  an end that does not taper (the section 6 mm inside the toe or heel end is more than
  0.7 of the ball girth: a crop, not a toe) says why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from app.geometry.sections import mesh_section_segments, tape_girths

#: points this close to the sole (mm) are its footprint
FOOTPRINT_MM = 25.0
#: shortest foot the rules are for (a child's foot is ~150 mm), mm
MIN_FOOT_MM = 150.0
#: the ball girth's window, as fractions of the foot length from the heel (module docstring)
BALL_WINDOW = (0.62, 0.78)
BALL_STEP_MM = 2.0
#: the foot's mid-plane, where the anterior profile is read: this close to it, mm
SAGITTAL_HALF_WIDTH_MM = 8.0
#: a mesh's mid-plane outline is subdivided to this spacing, mm
OUTLINE_STEP_MM = 1.0
#: where the front of the ankle is searched, fractions of the foot length from the heel
INSTEP_WINDOW = (0.15, 0.55)
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
    # the foot: below halfway from the sole to B (the forefoot is 40-55 mm high, B 100-150
    # mm above the sole; the shank's back above the heel would cut the heel's end planes)
    below_b, below_faces = _below(points, faces, 0.5 * sole_mm)
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
    return FootMeasures(foot_length, ball_point, _heel_instep(instep, instep_faces, axis, across, centre_x, heel_t, length))


def _sagittal_outline(points: np.ndarray, faces: np.ndarray | None, axis: np.ndarray, across: np.ndarray,
                      centre_x: float) -> np.ndarray:
    """The outline of the foot's mid-plane (x = centre_x across the foot) as (n, 2) points
    (along the foot axis, height) mm, at most OUTLINE_STEP_MM apart: a mesh's exact plane
    section (:func:`app.geometry.sections.mesh_section_segments`, each segment subdivided),
    a cloud's points within SAGITTAL_HALF_WIDTH_MM of the plane."""
    up = np.array([0.0, 0.0, 1.0])
    if faces is None or not len(faces):
        # a sparse cloud needs a thicker slab to hold the outline: twice its point spacing
        spacing = float(np.median(cKDTree(points).query(points, k=2)[0][:, 1]))
        near = points[np.abs(points @ across - centre_x) < max(SAGITTAL_HALF_WIDTH_MM, 2.0 * spacing)]
        return np.column_stack([near @ axis, near[:, 2]])
    local = points @ np.array([axis, up, across]).T
    _, segments = mesh_section_segments(local, faces, np.array([centre_x]))
    if not len(segments):
        return np.empty((0, 2))
    pieces = max(1, int(np.ceil(np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1).max() / OUTLINE_STEP_MM)))
    f = np.linspace(0.0, 1.0, pieces + 1)[None, :, None]
    return (segments[:, :1] * (1 - f) + segments[:, 1:] * f).reshape(-1, 2)


def _instep_point(outline: np.ndarray, heel_t: float, length: float) -> np.ndarray | None:
    """The front of the ankle, where the dorsum of the foot meets the shank, as (along the
    foot axis, height) mm, or None: on the anterior profile of the mid-plane outline (the
    front-most point of each 2 mm of height, from the toe tip up to B) the deepest point of
    the concave corner, the profile point furthest behind the chord from the toe tip to the
    shank's front at B.  Only front points count (ahead of the heel by INSTEP_WINDOW[0] of
    the foot length: a sparse scan's bin may hold only the back of the leg), and the corner
    is searched within INSTEP_WINDOW of the foot length from the heel (the talus neck, at
    the front of the ankle, lies 0.3-0.45 of it forward; the dorsum of the toes, further
    on, can dip too)."""
    outline = outline[(outline[:, 1] <= 0.0) & (outline[:, 0] > heel_t + INSTEP_WINDOW[0] * length)]
    if len(outline) < 20:
        return None
    t, z = outline[:, 0], outline[:, 1]
    edges = np.arange(z.min(), 1e-9, 2.0)
    if len(edges) < 8:
        return None
    bin_of = np.clip(np.digitize(z, edges) - 1, 0, len(edges) - 1)
    order = np.lexsort((t, bin_of))  # by bin, then forward: each bin's last is its front-most
    last = np.r_[bin_of[order][1:] != bin_of[order][:-1], True]
    profile = outline[order[last]]
    pt, pz = profile[:, 0], profile[:, 1]
    tip = int(np.argmax(pt))  # the toe tip
    top = len(profile) - 1  # the shank's front just below B
    if top - tip < 4:
        return None
    chord = np.array([pt[top] - pt[tip], pz[top] - pz[tip]])
    chord /= np.linalg.norm(chord)
    rel = profile[tip:top + 1] - profile[tip]
    behind = rel[:, 1] * chord[0] - rel[:, 0] * chord[1]  # > 0: behind the chord (towards the heel)
    behind[profile[tip:top + 1, 0] > heel_t + INSTEP_WINDOW[1] * length] = -np.inf
    deepest = int(np.argmax(behind))
    return profile[tip + deepest] if behind[deepest] > 0 else None


def _heel_instep(points: np.ndarray, faces: np.ndarray | None, axis: np.ndarray, across: np.ndarray,
                 centre_x: float, heel_t: float, length: float) -> FootPoint:
    """cY: the loop in the plane through the heel's posterior-inferior point and the front
    of the ankle (:func:`_instep_point`) that contains the foot's transverse axis."""
    up = np.array([0.0, 0.0, 1.0])
    back_down = -(axis + up) / np.sqrt(2.0)
    heel = points[int(np.argmax(points @ back_down))]
    front = _instep_point(_sagittal_outline(points, faces, axis, across, centre_x), heel_t, length)
    if front is None:
        return FootPoint("cY", None, reason="the front of the ankle (the fold over the instep) is not in the scan")
    instep = front[0] * axis + front[1] * up + centre_x * across
    rise = instep - heel
    rise -= (rise @ across) * across
    in_plane = rise / np.linalg.norm(rise)
    normal = np.cross(across, in_plane)
    girth = _plane_girths(points, faces, heel, np.array([across, in_plane, normal]), np.array([0.0]))[0]
    if not np.isfinite(girth):
        return FootPoint("cY", None, reason="no closed loop around the heel and the instep (a hole or a crop)")
    return FootPoint("cY", float(girth), _xyz((heel + instep) / 2))
