"""Pressure of a stretched fabric on the NURBS calf: Laplace's law P = T * kappa
(paper section 4).

At height h the fabric follows the *convex hull* of the leg's cross-section (it bridges
concavities); the local pressure is T * kappa where it touches the skin (kappa the
curvature of the contour, from the surface's own derivatives: The NURBS Book eq. 4.20
via :func:`app.geometry.spline.nurbs.evaluate_derivatives`; kappa = (x' y'' - y' x'') / |C'|^3
for the ring C(u) = S(u, v_h)) and 0 where it bridges; because the hull of a smooth
closed curve turns by exactly 2*pi along its contact arcs, the mean pressure around the
contour is 2*pi*T / L, L the hull perimeter.  Also the pressure per direction (medial,
lateral, anterior, posterior), hot spots above a limit, and the pressure map.

Units: lengths mm, tension N/cm, pressure Pa (1 mmHg = 133.322 Pa);
T [N/cm] * kappa [1/mm] = 1e5 * T * kappa Pa.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, sparse
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull

from app.geometry.anatomy.side import outer_side_angle
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.garment.fabric import Fabric
from app.geometry.spline.nurbs import NurbsSurface, evaluate_derivatives, evaluate_grid

PA_PER_MMHG = 133.322
#: tension [N/cm] x curvature [1/mm] -> pressure [Pa]
PA_PER_N_PER_CM_PER_MM = 1e5
#: a ring sample is in contact with the fabric when within this distance of the hull, mm
CONTACT_TOLERANCE_MM = 0.05

@dataclass(frozen=True)
class Rings:
    """Horizontal rings of the surface at k heights, n samples each (calf frame, mm).

    points (k, n, 2); curvature (k, n) 1/mm (positive where convex); arc (k, n) the arc
    length each sample stands for; contact (k, n) bool, on the hull; hull_perimeter (k,);
    perimeter (k,); centroid (k, 2); angle (k, n) direction of each sample from the
    centroid, radians.
    """

    heights_mm: np.ndarray
    u: np.ndarray
    v: np.ndarray
    points: np.ndarray
    z: np.ndarray
    curvature: np.ndarray
    arc: np.ndarray
    contact: np.ndarray
    hull_perimeter: np.ndarray
    perimeter: np.ndarray
    centroid: np.ndarray
    angle: np.ndarray


def heights_to_v(surface: NurbsSurface, heights: np.ndarray, samples: int = 2001) -> np.ndarray:
    """v parameters whose rings lie at the given calf-frame heights (mean z of the ring)."""
    v0, v1 = surface.domain_v
    u0, u1 = surface.domain_u
    v = np.linspace(v0, v1, samples)
    u = u0 + (u1 - u0) * np.arange(8) / 8
    z = evaluate_grid(surface, u, v)[..., 2].mean(axis=0)
    if np.any(np.diff(z) <= 0):
        raise FitFailure(FailureReason.INVALID_RECORD, "the surface's rings do not rise monotonically along v")
    heights = np.asarray(heights, dtype=float)
    if heights.min() < z[0] - 1e-6 or heights.max() > z[-1] + 1e-6:
        raise FitFailure(FailureReason.INVALID_TARGET, f"heights must lie between {z[0]:.1f} and {z[-1]:.1f} mm")
    return np.interp(heights, z, v)


def surface_rings(surface: NurbsSurface, heights: np.ndarray, n_around: int = 360) -> Rings:
    """Rings, curvature from the surface derivatives, and fabric contact (convex hull)."""
    heights = np.asarray(heights, dtype=float)
    v_of_h = heights_to_v(surface, heights)
    u0, u1 = surface.domain_u
    u = u0 + (u1 - u0) * np.arange(n_around) / n_around
    k = len(heights)
    uu = np.tile(u, k)
    vv = np.repeat(v_of_h, n_around)
    s, su, _, suu, _, _ = evaluate_derivatives(surface, uu, vv)
    points = s[:, :2].reshape(k, n_around, 2)
    z = s[:, 2].reshape(k, n_around)
    dx, dy = su[:, 0], su[:, 1]
    ddx, ddy = suu[:, 0], suu[:, 1]
    speed = np.hypot(dx, dy)
    curvature = ((dx * ddy - dy * ddx) / speed**3).reshape(k, n_around)
    # arc length per sample: |C'| du
    arc = (speed * (u1 - u0) / n_around).reshape(k, n_around)
    contact = np.zeros((k, n_around), dtype=bool)
    hull_perimeter = np.zeros(k)
    for i in range(k):  # one hull per ring (k ~ 60); everything inside is vectorized
        ring = points[i]
        hull = ConvexHull(ring)
        hull_perimeter[i] = hull.area  # in 2-D, "area" is the perimeter
        contact[i] = _contact(ring, np.sort(hull.vertices))
    nxt = np.roll(points, -1, axis=1)
    perimeter = np.linalg.norm(nxt - points, axis=2).sum(axis=1)
    centroid = points.mean(axis=1)
    rel = points - centroid[:, None, :]
    angle = np.mod(np.arctan2(rel[..., 1], rel[..., 0]), 2 * np.pi)
    return Rings(heights, u, v_of_h, points, z, curvature, arc, contact, hull_perimeter, perimeter, centroid, angle)


def _contact(ring: np.ndarray, hull_vertices: np.ndarray) -> np.ndarray:
    """(n,) bool: ring samples within CONTACT_TOLERANCE_MM of the hull boundary.

    Each sample lies under the hull edge between the hull vertices before and after it
    (in ring order); its distance to that edge's line tells whether the fabric touches.
    """
    n = len(ring)
    index = np.arange(n)
    slot = np.searchsorted(hull_vertices, index, side="right") - 1  # previous hull vertex
    a = hull_vertices[slot % len(hull_vertices)]
    b = hull_vertices[(slot + 1) % len(hull_vertices)]
    pa, pb = ring[a], ring[b]
    edge = pb - pa
    length = np.linalg.norm(edge, axis=1)
    rel = ring - pa
    distance = np.abs(edge[:, 0] * rel[:, 1] - edge[:, 1] * rel[:, 0]) / np.maximum(length, 1e-12)
    return (distance < CONTACT_TOLERANCE_MM) | np.isin(index, hull_vertices)


def local_pressure_pa(rings: Rings, tension_n_per_cm: np.ndarray) -> np.ndarray:
    """(k, n) Laplace pressure T * kappa on the skin, 0 where the fabric bridges, Pa."""
    kappa = np.where(rings.contact, np.maximum(rings.curvature, 0.0), 0.0)
    return PA_PER_N_PER_CM_PER_MM * np.asarray(tension_n_per_cm)[:, None] * kappa


def mean_pressure_pa(rings: Rings, tension_n_per_cm: np.ndarray) -> np.ndarray:
    """(k,) mean pressure around the hull, 2 pi T / L, Pa."""
    return laplace_mean_pa(tension_n_per_cm, rings.hull_perimeter)


def laplace_mean_pa(tension_n_per_cm: np.ndarray, hull_length_mm: np.ndarray) -> np.ndarray:
    """(k,) mean pressure (Pa) of fabric at ``tension_n_per_cm`` round a convex hull of
    length ``hull_length_mm``: 2 pi T / L (Laplace averaged round the hull)."""
    return PA_PER_N_PER_CM_PER_MM * 2 * np.pi * np.asarray(tension_n_per_cm) / np.asarray(hull_length_mm)


def sector_means(rings: Rings, pressure: np.ndarray, directions: dict[str, float], half_width_deg: float = 10.0) -> dict:
    """Mean local pressure (arc-length weighted) in a sector around each direction.

    directions: name -> angle (radians, calf frame); returns name -> (k,) Pa.  A sensor
    (e.g. the paper's mannequin measurement) reads an area, not a point: +-10 degrees.
    """
    out = {}
    half = np.deg2rad(half_width_deg)
    for name, theta in directions.items():
        delta = np.abs((rings.angle - theta + np.pi) % (2 * np.pi) - np.pi)
        weight = rings.arc * (delta <= half)
        out[name] = (pressure * weight).sum(axis=1) / np.maximum(weight.sum(axis=1), 1e-12)
    return out


def side_directions(side: str | None) -> tuple[dict[str, float], bool]:
    """Medial/lateral/anterior/posterior angles in the calf frame (x = subject's right,
    y = anterior).  Medial points to the body's midline: -x for a right leg, +x for a
    left leg.  Unknown side: a right leg is assumed (second value True)."""
    outer = outer_side_angle(side)
    lateral = 0.0 if outer is None else outer
    return {"medial": (lateral + np.pi) % (2 * np.pi), "lateral": lateral, "anterior": np.pi / 2,
            "posterior": 3 * np.pi / 2}, outer is None


def sector_name(angle: float, directions: dict[str, float]) -> str:
    names = list(directions)
    diffs = [abs((angle - directions[n] + np.pi) % (2 * np.pi) - np.pi) for n in names]
    return names[int(np.argmin(diffs))]


@dataclass(frozen=True)
class HotSpot:
    """A connected region where local pressure exceeds the limit: its peak (Pa) and
    where it is (height mm of the peak and the region's height extent, the peak's angle
    in degrees and its sector name), and its size in grid samples."""

    height_mm: float
    from_height_mm: float
    to_height_mm: float
    angle_deg: float
    side: str
    peak_pa: float
    samples: int

    @property
    def peak_mmhg(self) -> float:
        return self.peak_pa / PA_PER_MMHG


def find_hot_spots(rings: Rings, local_pa: np.ndarray, limit_pa: float, directions: dict[str, float]) -> list[HotSpot]:
    """Connected regions of the (height x angle) grid where local pressure > limit, the
    highest peak first.

    Regions are labelled with scipy.ndimage; a region crossing the angle seam (the first
    and last columns) is one region: the labels that touch across it are joined as
    connected components of a graph (scipy.sparse.csgraph).  Peak, height extent and
    size per region come from ndimage reductions.
    """
    above = local_pa > limit_pa
    labels, count = ndimage.label(above)
    if count == 0:
        return []
    seam = above[:, 0] & above[:, -1]
    pairs = sparse.coo_matrix((np.ones(int(seam.sum())), (labels[seam, 0], labels[seam, -1])), shape=(count + 1, count + 1))
    _, component = connected_components(pairs, directed=False)
    merged = np.where(labels > 0, component[labels] + 1, 0)
    ids = np.unique(merged[merged > 0])
    rows = np.broadcast_to(np.arange(local_pa.shape[0])[:, None], local_pa.shape)
    peaks = ndimage.maximum_position(local_pa, merged, ids)
    lowest = ndimage.minimum(rows, merged, ids)
    highest = ndimage.maximum(rows, merged, ids)
    sizes = ndimage.sum(above, merged, ids)
    spots = []
    for (r, c), lo, hi, size in zip(peaks, lowest, highest, sizes):  # one per region (a handful)
        angle = float(rings.angle[r, c])
        spots.append(HotSpot(
            height_mm=float(rings.heights_mm[r]),
            from_height_mm=float(rings.heights_mm[int(lo)]),
            to_height_mm=float(rings.heights_mm[int(hi)]),
            angle_deg=float(np.degrees(angle)),
            side=sector_name(angle, directions),
            peak_pa=float(local_pa[r, c]),
            samples=int(size),
        ))
    return sorted(spots, key=lambda spot: -spot.peak_pa)


def pressure_map(surface: NurbsSurface, design: dict, fabric: Fabric, n_around: int = 360) -> tuple[Rings, np.ndarray]:
    """Local pressure (Pa) on a (heights, n_around) grid, from the design's knitting spec.

    Heights every 2.5 mm from B to D, where the surface is (a thigh-high's spec runs on to
    G on the thigh's tape girths, and the foot's rows lie below B: off the surface, no
    local map there); tension interpolated from the spec's leg rows (the top band's with
    the band's tension) in height.
    """
    spec = [row for row in design["knitting_spec"] if row.get("part", "leg") != "foot"]
    h_spec = np.array([row["height_mm"] for row in spec])
    t_spec = np.array([row["tension_N_per_cm"] for row in spec])
    top = min(float(h_spec[-1]), float(design["landmarks"]["D"]["height_mm"]))
    heights = np.arange(h_spec[0], top + 1e-9, 2.5)
    rings = surface_rings(surface, heights, n_around)
    return rings, local_pressure_pa(rings, np.interp(heights, h_spec, t_spec))
