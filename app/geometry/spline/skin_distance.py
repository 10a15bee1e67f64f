"""How far the surface stands off the scan: the other side of the error index.

The error index E (paper eq. 4) and the max error measure scan -> surface: every scan
point's distance to the surface.  A surface can satisfy them and still leave the skin
where no scan point pulls it - an lsq border row free of data, a fold between layers -
and a stocking knitted from it is then wrong.  :func:`surface_to_scan` samples the
surface densely over its whole domain (:data:`SAMPLES_AROUND` x one row per
:data:`ROW_SPACING_MM` of height) and measures each sample's distance to the scan:

- a mesh: the closest point on the triangles around the sample's
  :data:`NEAREST_VERTICES` nearest vertices and :data:`NEAREST_TRIANGLES` nearest
  triangle centroids (Ericson 5.1.5, via
  :func:`app.geometry.spline.distance.point_triangle_offsets`);
- a cloud: the distance to the nearest point (an upper bound: on the skin it is up
  to about the point spacing, so a cloud's off-skin threshold is :data:`OFF_SKIN_MM`
  plus its median point spacing).

Only samples **where the scan has data** count: a sample whose nearest skin point
(a cloud's nearest point; a mesh's closest point on its triangles) lies across the surface
from it - its offset mostly along the normal, tangentially within
:data:`TANGENT_SLACK_MM` plus its normal part - faces skin; one whose nearest skin lies
beside it (the rim of a hole, past a cropped end) faces none and is left out: there the
surface bridges by design.
The result gives the median, p99 and max over the counted samples, the share of the
surface the scan covers, and where the worst sample lies.  Units: mm; calf frame.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

from app.geometry.scan.mesh_parts import used_vertices
from app.geometry.spline.distance import point_triangle_offsets
from app.geometry.spline.nurbs import NurbsSurface, evaluate_derivatives

SAMPLES_AROUND = 72
ROW_SPACING_MM = 3.0
NEAREST_VERTICES = 3
NEAREST_TRIANGLES = 12
#: at most this many triangles around one vertex are tested (a mesh vertex has ~6)
FACES_PER_VERTEX = 8
#: skin this far beyond the calf's ends still counts (a surface flaring past B or D)
MARGIN_MM = 10.0
#: a sample's nearest skin may lie this far beside it (a cloud's point spacing; the
#: facets of a mesh) and still count as skin across from it
TANGENT_SLACK_MM = 2.0
#: a surface further than this from skin the scan has is off the skin
OFF_SKIN_MM = 3.0
#: ... and warned about when an arc of a ring this large (a share of its samples: 5% is
#: 18 degrees) stands off: a fold the surface bridges (behind the knee, 1-2 samples of a
#: ring) is what a tape and a stocking bridge too; an arc changes the ring's girth
OFF_SKIN_RING_SHARE = 0.05


@dataclass(frozen=True)
class SkinDistance:
    """Surface -> scan distances over the samples where the scan has data (mm)."""

    median_mm: float
    p99_mm: float
    max_mm: float
    coverage: float  # share of the surface samples where the scan has data
    off_skin_share: float  # share of the counted samples more than OFF_SKIN_MM off
    worst_height_mm: float  # calf-frame z of the worst counted sample
    worst_v: float  # its v (0: B, 1: D)
    n_samples: int
    #: the largest share of one ring's counted samples (a row of constant v) that is more
    #: than OFF_SKIN_MM off: an arc of the ring, which changes its girth
    worst_ring_share: float = 0.0
    worst_ring_height_mm: float = float("nan")

    @property
    def off_skin(self) -> bool:
        """An arc of at least OFF_SKIN_RING_SHARE of some ring stands off the skin."""
        return self.worst_ring_share >= OFF_SKIN_RING_SHARE

    @property
    def off_skin_text(self) -> str:
        """Where and how far the surface stands off, in words (the fit's warning and the
        design's review reason say it)."""
        return (f"stands up to {self.max_mm:.1f} mm off the scan's skin: {self.worst_ring_share:.0%} of its ring at "
                f"{self.worst_ring_height_mm:.0f} mm above B is more than {OFF_SKIN_MM:g} mm off")

    @classmethod
    def from_dict(cls, data) -> SkinDistance | None:
        """The distances as a record stores them (:meth:`as_dict`; fields a record made
        before they were kept take their defaults), or None when ``data`` is not such a
        dict (a record imported from elsewhere carries its ``fit`` as it likes)."""
        if not isinstance(data, dict):
            return None
        try:
            values: dict[str, Any] = {f.name: float(data[f.name]) for f in fields(cls) if f.name in data}
            if "n_samples" in values:
                values["n_samples"] = int(values["n_samples"])
            return cls(**values)
        except (TypeError, ValueError, OverflowError):
            return None

    def as_dict(self) -> dict:
        return {"median_mm": self.median_mm, "p99_mm": self.p99_mm, "max_mm": self.max_mm, "coverage": self.coverage,
                "off_skin_share": self.off_skin_share, "worst_height_mm": self.worst_height_mm,
                "worst_v": self.worst_v, "n_samples": self.n_samples, "worst_ring_share": self.worst_ring_share,
                "worst_ring_height_mm": self.worst_ring_height_mm}


def _faces_of_vertices(faces: np.ndarray, n_vertices: int) -> np.ndarray:
    """(n_vertices, FACES_PER_VERTEX) face indices around each vertex in rising order,
    each face once (a degenerate face naming a vertex twice too), -1 padded.  The faces
    grouped by corner vertex as scipy's COO -> CSR conversion does it (a counting sort):
    on a 126k-face mesh 6 ms where a stable argsort of the corners took 29."""
    corners = faces.ravel()
    owner = np.repeat(np.arange(len(faces)), 3)
    grouped = sparse.csr_matrix((np.ones(len(corners), dtype=np.int8), (corners, owner)),
                                shape=(n_vertices, len(faces)))
    starts, counts = grouped.indptr[:-1], np.diff(grouped.indptr)
    slot = np.arange(FACES_PER_VERTEX)
    index = np.minimum(starts[:, None] + slot[None, :], max(len(grouped.indices) - 1, 0))
    return np.where(slot[None, :] < counts[:, None], grouped.indices[index], -1)


def _offsets_to_mesh(samples: np.ndarray, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(s, 3) mm from each sample (s, 3) to its closest point on the mesh (Ericson 5.1.5)
    among the candidate triangles: those round its NEAREST_VERTICES nearest vertices and
    its NEAREST_TRIANGLES nearest triangle centroids.  The vertices alone miss a large
    triangle whose closest point is deep inside it, far from its corners (on BodyParts3D's
    coarse calf they read a sample on the skin 8.8 mm off); its centroid is near.  Not a
    proof of the closest (a bounding-volume search would be): measured on BodyParts3D's
    27k-face leg against the distance to points every 2 mm on every triangle, 12 centroids
    are never further on any of 6,192 samples, 4 were up to 0.9 mm further on 12.

    Only the candidates that may be nearest are measured exactly: a triangle lies in the
    ball about its centroid through its furthest corner, so it is at least the distance
    to its centroid less that ball's radius away, and a candidate whose bound passes the
    sample's nearest vertex (a point on its own triangles, which are candidates) cannot be
    the nearest.  The offsets are those of every candidate measured; about half the
    exact distances are left out (benchmarks/bench_fit.py, the fit's time)."""
    reach, nearest = cKDTree(vertices).query(samples, k=NEAREST_VERTICES)
    table = _faces_of_vertices(faces, len(vertices))
    centroids = vertices[faces].mean(axis=1)
    ball = np.sqrt(np.max(np.sum((vertices[faces] - centroids[:, None, :]) ** 2, axis=2), axis=1))  # (f,)
    to_centroid, near_faces = cKDTree(centroids).query(samples, k=min(NEAREST_TRIANGLES, len(faces)))
    # the nearest vertex and the nearest centroid are points on the mesh: the closest is no further
    bound = np.minimum(reach.reshape(len(samples), -1)[:, 0], to_centroid.reshape(len(samples), -1)[:, 0])
    candidates = np.sort(np.concatenate([table[nearest].reshape(len(samples), -1), near_faces.reshape(len(samples), -1)],
                                        axis=1), axis=1)  # (s, k * F + t), the -1 padding first
    # each triangle once (a triangle round two of the nearest vertices is also among the
    # nearest centroids), the distinct (sample, triangle) pairs flattened row by row
    distinct = candidates >= 0
    distinct[:, 1:] &= candidates[:, 1:] != candidates[:, :-1]
    sample = np.nonzero(distinct)[0]  # (p,) rising: each sample's pairs are contiguous
    face = candidates[distinct]
    gap = samples[sample] - centroids[face]
    may_be_nearest = np.sqrt(np.einsum("pd,pd->p", gap, gap)) - ball[face] <= bound[sample] + 1e-6
    sample, face = sample[may_be_nearest], face[may_be_nearest]
    tri = faces[face]  # (p, 3)
    away = point_triangle_offsets(samples[sample], vertices[tri[:, 0]], vertices[tri[:, 1]],
                                  vertices[tri[:, 2]])  # (p, 3): sample - closest point
    distance = np.einsum("pd,pd->p", away, away)
    # each sample's nearest pair: the first of its pairs at its least distance (every
    # sample keeps the triangle its bound was read on, the 1e-6 mm a rounding's room - so
    # the runs' minima are indexed by sample)
    least = np.minimum.reduceat(distance, np.flatnonzero(np.r_[True, sample[1:] != sample[:-1]]))
    hit = np.flatnonzero(distance == least[sample])
    first = hit[np.r_[True, sample[hit][1:] != sample[hit][:-1]]]
    return -away[first]


def surface_to_scan(surface: NurbsSurface, points: np.ndarray, faces: np.ndarray | None,
                    low_mm: float, high_mm: float, row_spacing_mm: float = ROW_SPACING_MM) -> SkinDistance:
    """Surface -> scan distances (module docstring).  points (n, 3) calf-frame mm, faces
    (f, 3) or None; the scan's skin counts between ``low_mm`` and ``high_mm`` (and
    :data:`MARGIN_MM` beyond); a ring of samples every ``row_spacing_mm`` of height."""
    if faces is not None and not len(faces):
        faces = None
    if faces is not None:  # only the triangles of the skin that counts (and only their vertices: a hole's are no skin)
        z = points[:, 2][faces]
        faces = faces[(z.max(axis=1) >= low_mm - MARGIN_MM) & (z.min(axis=1) <= high_mm + MARGIN_MM)]
        used, faces = used_vertices(faces, len(points))
        points = points[used]
    else:
        points = points[(points[:, 2] >= low_mm - MARGIN_MM) & (points[:, 2] <= high_mm + MARGIN_MM)]
    if not len(points):
        return SkinDistance(float("nan"), float("nan"), float("nan"), 0.0, 0.0, float("nan"), float("nan"), 0)
    u0, u1 = surface.domain_u
    v0, v1 = surface.domain_v
    rows = max(int(np.ceil((high_mm - low_mm) / row_spacing_mm)) + 1, 8)
    u = u0 + (u1 - u0) * np.arange(SAMPLES_AROUND) / SAMPLES_AROUND
    v = np.linspace(v0, v1, rows)
    uu, vv = np.meshgrid(u, v, indexing="ij")
    samples, su, sv, _, _, _ = evaluate_derivatives(surface, uu.ravel(), vv.ravel())
    normal = np.cross(su, sv)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    allowance = 0.0
    if faces is not None:  # the exact closest point of the skin
        offset = _offsets_to_mesh(samples, points, faces)
    else:  # a cloud's nearest point
        tree = cKDTree(points)
        _, nearest = tree.query(samples)
        offset = points[nearest] - samples
        # on the skin, a sample's nearest point of a cloud is up to about the point
        # spacing away: the off-skin threshold grows by the cloud's median spacing
        some = points[:: max(len(points) // 5000, 1)]
        allowance = float(np.median(tree.query(some, k=2)[0][:, 1])) if len(points) > 1 else 0.0
    along_normal = np.einsum("ij,ij->i", offset, normal)
    tangential = np.linalg.norm(offset - along_normal[:, None] * normal, axis=1)
    # the scan has skin here when its nearest skin lies across the surface (off it or on
    # it), not beside it (the rim of a hole, past a cropped end)
    counted = tangential <= TANGENT_SLACK_MM + np.abs(along_normal)
    distance = np.linalg.norm(offset[counted], axis=1)
    if not len(distance):
        return SkinDistance(float("nan"), float("nan"), float("nan"), 0.0, 0.0, float("nan"), float("nan"), 0)
    worst = int(np.argmax(distance))
    row = np.broadcast_to(np.arange(rows)[None, :], (SAMPLES_AROUND, rows)).ravel()[counted]
    per_ring = np.bincount(row, minlength=rows)
    off = np.bincount(row, weights=(distance > OFF_SKIN_MM + allowance).astype(float), minlength=rows)
    share = np.divide(off, per_ring, out=np.zeros(rows), where=per_ring >= SAMPLES_AROUND // 4)
    ring = int(np.argmax(share))
    return SkinDistance(
        median_mm=float(np.median(distance)), p99_mm=float(np.percentile(distance, 99)), max_mm=float(distance[worst]),
        coverage=float(counted.mean()), off_skin_share=float((distance > OFF_SKIN_MM + allowance).mean()),
        worst_height_mm=float(samples[counted][worst, 2]), worst_v=float(vv.ravel()[counted][worst]),
        n_samples=int(counted.sum()), worst_ring_share=float(share[ring]),
        worst_ring_height_mm=float(np.median(samples.reshape(SAMPLES_AROUND, rows, 3)[:, ring, 2])))
