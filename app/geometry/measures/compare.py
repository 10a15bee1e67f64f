"""Two records of one leg compared: girth profiles, volume change, a signed difference map.

What limb-volume devices (the Perometer) give lymphoedema clinics, from the exact
surfaces: the legs are aligned along the calf axis at a landmark (B by default: in each
record heights are then measured from its own B), the girths of both surfaces are read
every :data:`STEP_MM` over the heights both cover, the volumes between the same two
aligned heights (the first record's B and D, clipped to what both cover) are computed
exactly (:mod:`app.geometry.measures.volume`), and every vertex of a dense tessellation of the
first surface gets its signed distance to the second (exact foot points by Newton,
:mod:`app.geometry.spline.distance`): positive where the second surface lies outside the
first (the leg has grown there), negative where it lies inside.

Units: mm, mm^3 (the service reports ml).  Both surfaces in their calf frames (B at
z = 0 of each, z up the leg): aligning at a landmark is a shift along z only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.measures.surface_girths import girths, surface_height_range
from app.geometry.measures.volume import cut_height_range, volume_between
from app.geometry.spline.distance import foot_points
from app.geometry.spline.nurbs import NurbsSurface, evaluate_derivatives
from app.geometry.spline.tessellation import tessellate

STEP_MM = 5.0
ALIGN_LANDMARKS = ("B", "B1", "C", "D")


@dataclass(frozen=True)
class Comparison:
    """heights_mm (k,) above the alignment landmark; girth_a_mm / girth_b_mm (k,) the
    tape girths there; volume_a_mm3 / volume_b_mm3 between low_mm and high_mm (heights
    above the landmark); shift_mm: b's z = a's z + shift_mm."""

    align: str
    shift_mm: float
    heights_mm: np.ndarray
    girth_a_mm: np.ndarray
    girth_b_mm: np.ndarray
    low_mm: float
    high_mm: float
    volume_a_mm3: float
    volume_b_mm3: float

    @property
    def volume_change_mm3(self) -> float:
        return self.volume_b_mm3 - self.volume_a_mm3

    @property
    def volume_change_percent(self) -> float:
        return 100.0 * self.volume_change_mm3 / self.volume_a_mm3


def landmark_height(landmarks: dict, name: str) -> float:
    return float(landmarks[name]["height_mm"])


def alignment_shift(landmarks_a: dict, landmarks_b: dict, align: str) -> float:
    """b's calf-frame z minus a's at the landmark ``align`` (mm): b's z = a's z + shift."""
    return landmark_height(landmarks_b, align) - landmark_height(landmarks_a, align)


def shared_heights(a: NurbsSurface, b: NurbsSurface, shift_mm: float) -> tuple[float, float]:
    """(low, high) of a's z that both surfaces cover once b is shifted by ``shift_mm``;
    ValueError when that is less than 20 mm of leg."""
    a0, a1 = cut_height_range(a)
    b0, b1 = cut_height_range(b)
    lo, hi = max(a0, b0 - shift_mm), min(a1, b1 - shift_mm)
    if hi - lo < 20.0:
        raise ValueError("the two calves share less than 20 mm of leg once aligned")
    return lo, hi


def compare_surfaces(a: NurbsSurface, landmarks_a: dict, b: NurbsSurface, landmarks_b: dict,
                     align: str = "B", step_mm: float = STEP_MM) -> Comparison:
    """The comparison of record b against record a (module docstring).  Landmark dicts:
    name -> {"height_mm": ...}.  Raises ValueError when the aligned surfaces share less
    than 20 mm of leg."""
    base_a, base_b = landmark_height(landmarks_a, align), landmark_height(landmarks_b, align)
    shift = alignment_shift(landmarks_a, landmarks_b, align)
    lo, hi = shared_heights(a, b, shift)
    first = np.ceil((lo + 1e-6 - base_a) / step_mm) * step_mm
    heights = np.arange(first, hi - base_a - 1e-6 + 1e-9, step_mm)  # above the landmark
    girth_a = np.array([g.tape_mm for g in girths(a, heights + base_a)])
    girth_b = np.array([g.tape_mm for g in girths(b, heights + base_b)])
    # the volume over a's B to D, clipped to the shared heights (10 um inside the ends)
    low = max(landmark_height(landmarks_a, "B"), lo + 1e-2)
    high = min(landmark_height(landmarks_a, "D"), hi - 1e-2)
    volume_a = volume_between(a, low, high)
    volume_b = volume_between(b, low + shift, high + shift)
    return Comparison(align, float(shift), heights, girth_a, girth_b, float(low - base_a), float(high - base_a),
                      volume_a, volume_b)


def signed_differences(a: NurbsSurface, b: NurbsSurface, shift_mm: float, n_around: int = 144,
                       n_along: int = 100) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Signed distance from surface a to surface b at every vertex of a's tessellation.

    Returns vertices (n, 3) in a's calf frame, faces (f, 3), signed (n,) mm: positive
    where b lies outside a along a's outward normal.  Vertices whose foot point on b
    lies on b's end rings (b does not reach that height) are NaN.
    """
    vertices, faces = tessellate(a, n_around, n_along)
    points = vertices + np.array([0.0, 0.0, shift_mm])  # in b's frame
    z0, z1 = surface_height_range(b)
    distance, fu, fv = foot_points(b, points, z1 - z0)
    s, su, sv, _, _, _ = evaluate_derivatives(b, fu, fv)
    normal = np.cross(su, sv) * _outward(b)
    sign = np.sign(np.einsum("ij,ij->i", s - points, normal))  # b outside a: the foot lies outward
    signed = sign * distance
    v0, v1 = b.domain_v
    signed[(fv <= v0 + 1e-9) | (fv >= v1 - 1e-9)] = np.nan
    return vertices, faces, signed


def _outward(surface: NurbsSurface) -> float:
    """+1 when S_u x S_v points out of the tube, -1 when in (one orientation for the
    whole surface): tested on its middle ring, against the ring's centroid."""
    u = np.linspace(*surface.domain_u, 36, endpoint=False)
    v = np.full(36, 0.5 * sum(surface.domain_v))
    s, su, sv, _, _, _ = evaluate_derivatives(surface, u, v)
    radial = s[:, :2] - s[:, :2].mean(axis=0)
    return 1.0 if np.einsum("ij,ij->", np.cross(su, sv)[:, :2], radial) > 0 else -1.0
