"""Is a point cloud's skin one layer, or two?  A cloud whose skin is doubled.

A scanner whose passes were exported without being merged, or a leg that moved between
two passes, gives a cloud with the skin twice: two shells a few mm apart.  The
sections' robust fit (:mod:`app.geometry.sections.cloud`) then takes, bin by bin, a
median that jumps between the shells, and the tape - the convex hull of that contour -
rides the outer one: on generated legs two shells 2.5-6 mm apart read the calf's girths
up to 5.1 mm wide, and cE, whose E moved with them, 10.7 mm (benchmarks/results/motion.md).
The worst case is geometry: the convex hull of two copies of a section offset by d is
2 d longer than one copy's.  Nothing else in the
cloud betrays it, so :func:`skin_layers` measures it.

Method (statistics of the skin's thickness, no threshold tuned to a scanner):

1. about :data:`NEIGHBOURHOODS` neighbourhoods of :data:`NEIGHBOURS` points each, seeded
   evenly through the cloud;
2. in each, the points' local frame (PCA: the normal is the least-variance direction)
   and a quadric height ``h = a u^2 + b uv + c v^2 + d u + e v + f`` fitted by least
   squares: the skin's curvature leaves the residuals, what remains is the skin's
   thickness - a scanner's noise (one layer) or two layers;
3. per neighbourhood, Sarle's bimodality coefficient of the residuals,
   BC = (g1^2 + 1) / g2 from their skewness g1 and kurtosis g2 (SAS/STAT manual; Pfister
   et al. 2013, "Good things peak in pairs", Front. Psychol. 4:700): a Gaussian has 1/3, a
   uniform 5/9, two separate peaks of any shares (a second pass with a fifth of the
   points as much as an equal one) up to 1; and the layers' separation, twice the
   residuals' sd (two equal layers d apart without noise have sd d / 2; noise makes it
   larger, an unequal share smaller).

One noisy layer is Gaussian: the median coefficient over the neighbourhoods measured
0.35-0.39 on clouds drawn from a generated leg clean, with 0.5, 1 and 1.5 mm of noise,
sampled 4x sparser on one side, and a tessellation's vertices; 0.34-0.42 on the 178
generated cloud scans of benchmarks/corpus (seeds 7 and 11: 11 kinds, stray points the
highest) and the three real legs read as clouds.  Two layers measured
0.54-0.87: 2-6 mm apart, equal or 30 / 70 or 20 / 80 shares, with up to 1 mm of noise
(1 mm on layers 6 mm apart is the lowest, 0.54; the textbook bound 5/9 would miss it, so
the threshold :data:`BIMODAL_COEFFICIENT` lies between the two groups).  The skin is
doubled when the median coefficient is above it and the 90th percentile of the
separation (the layers lie apart along the normal only where the move between them
does: the 90th percentile reads the sides that face it) is at least :data:`DOUBLED_MM`.

Units: mm.  points (n, 3), any frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

#: neighbourhoods measured, seeded evenly through the cloud's points
NEIGHBOURHOODS = 1500
#: points per neighbourhood: at a scanner's 1-1.5 mm spacing they reach 5-7 mm, wider than
#: the layers' separation (a narrower one holds a single layer, 40 points read two layers
#: 6 mm apart as 4)
NEIGHBOURS = 96
#: a single layer's neighbourhoods have a median bimodality coefficient of 0.34-0.42
#: (Gaussian 1/3, and a sample of 96; stray points the highest), two layers' 0.54-0.87
#: (module docstring): midway
BIMODAL_COEFFICIENT = 0.48
#: two layers this far apart (90th percentile) are warned about: on generated legs 3 mm
#: read the girths up to 1.2 mm wide, 2.5-6 mm the calf's up to 5.1 mm (benchmarks/motion.py)
DOUBLED_MM = 2.5


@dataclass(frozen=True)
class SkinLayers:
    """How thick a cloud's skin is: one layer or two (module docstring)."""

    bimodality: float  # the median of the neighbourhoods' bimodality coefficients
    separation_p90_mm: float
    neighbourhoods: int

    @classmethod
    def from_dict(cls, data) -> SkinLayers | None:
        """The layers as a record's ``fit.skin_layers`` stores them (:meth:`as_dict`), or
        None when ``data`` is not such a dict (a mesh's record, one made before they were
        kept, one imported from elsewhere)."""
        if not isinstance(data, dict):
            return None
        try:
            return cls(float(data["bimodality"]), float(data["separation_p90_mm"]), int(data["neighbourhoods"]))
        except (KeyError, TypeError, ValueError, OverflowError):
            return None

    def as_dict(self) -> dict:
        return {"bimodality": self.bimodality, "separation_p90_mm": self.separation_p90_mm,
                "neighbourhoods": self.neighbourhoods, "doubled": self.doubled}

    @property
    def doubled(self) -> bool:
        return self.bimodality > BIMODAL_COEFFICIENT and self.separation_p90_mm >= DOUBLED_MM

    @property
    def doubled_text(self) -> str:
        """The fit's warning, in words."""
        return (f"the cloud holds the skin twice, about {self.separation_p90_mm:.0f} mm apart (two passes of the "
                "scanner exported without being merged, or the leg moved between them): the girths may read up to "
                f"{2 * self.separation_p90_mm:.0f} mm wide (the tape rides the outer layer) and the points placed on "
                "the girth profile (E, F, G) may move with it; export the merged scan, or scan again standing still")


def skin_layers(points: np.ndarray) -> SkinLayers | None:
    """The skin's layers in ``points`` (n, 3) mm (module docstring); None when there are
    too few points to measure neighbourhoods."""
    points = np.asarray(points, dtype=np.float64)
    if len(points) < 4 * NEIGHBOURS:
        return None
    seeds = points[:: max(len(points) // NEIGHBOURHOODS, 1)]
    _, nearest = cKDTree(points).query(seeds, k=NEIGHBOURS)
    local = points[nearest]
    local -= local.mean(axis=1, keepdims=True)  # (s, k, 3)
    _, axes = np.linalg.eigh(np.matmul(local.transpose(0, 2, 1), local))  # ascending: the normal first
    u, v, h = np.moveaxis(np.matmul(local, axes[:, :, ::-1]), -1, 0)  # (s, k) each: along, across, normal
    design = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=-1)  # (s, k, 6)
    transposed = design.transpose(0, 2, 1)
    normal = np.matmul(transposed, design) + 1e-9 * np.eye(6)
    coefficients = np.linalg.solve(normal, np.matmul(transposed, h[..., None]))  # (s, 6, 1)
    residual = h - np.matmul(design, coefficients)[..., 0]
    residual -= residual.mean(axis=1, keepdims=True)
    squared = residual * residual
    m2 = np.maximum(squared.mean(axis=1), 1e-18)
    skewness = (squared * residual).mean(axis=1) / m2**1.5
    kurtosis = (squared * squared).mean(axis=1) / m2**2
    coefficient = (skewness**2 + 1.0) / kurtosis
    separation = 2.0 * np.sqrt(m2)
    return SkinLayers(float(np.median(coefficient)), float(np.percentile(separation, 90)), len(seeds))
