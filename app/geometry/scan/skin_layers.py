"""Is a point cloud's skin one layer, or two?  A cloud whose skin is doubled.

A scanner whose passes were exported without being merged, or a leg that moved between
two passes, gives a cloud with the skin twice: two shells a few mm apart.  The
sections' robust fit (:mod:`app.geometry.sections.cloud`) then takes, bin by bin, a
median that jumps between the shells, and the tape - the convex hull of that contour -
rides the outer one: on generated legs two equal shells 6 mm apart read the girths up
to 4 mm wide, 3 mm apart up to 1.2 mm.  The worst case is geometry: the convex hull of
two copies of a section offset by d is 2 d longer than one copy's.  Nothing else in the
cloud betrays it, so :func:`skin_layers` measures it.

Method (a statistic of the skin's thickness, no threshold tuned to a scanner):

1. about :data:`NEIGHBOURHOODS` neighbourhoods of :data:`NEIGHBOURS` points each, seeded
   evenly through the cloud;
2. in each, the points' local frame (PCA: the normal is the least-variance direction)
   and a quadric height ``h = a u^2 + b uv + c v^2 + d u + e v + f`` fitted by least
   squares: the skin's curvature leaves the residuals, what remains is the skin's
   thickness - a scanner's noise (one layer) or two layers;
3. per neighbourhood, the residuals' kurtosis m4 / m2^2 and the separation of two equal
   layers that would give them: for a mixture of two Gaussians of sd s at -a and +a,
   m2 = s^2 + a^2 and m4 = 3 s^4 + 6 s^2 a^2 + a^4, so a^4 = (3 m2^2 - m4) / 2 (method
   of moments; clipped at 0) and the layers are 2a apart.

One noisy layer has Gaussian residuals: kurtosis near 3 (the median over neighbourhoods
measured 2.8-3.0 on generated clouds clean, with 0.5 and 1 mm of noise, sampled 4x
sparser on one side, and a tessellation's vertices), and a small apparent separation
(about 1.4 sd at the 90th percentile: the sampling error of m4).  Two layers have a
bimodal residual: median kurtosis 1.3-2.1 (equal layers 2-6 mm apart, with and without
noise; a 30% / 70% split).  The skin is doubled when the median kurtosis is under
:data:`BIMODAL_KURTOSIS` and the 90th percentile of the separation (the layers lie apart
along the normal only where the offset between them is: the 90th percentile reads the
sides that face it) is at least :data:`DOUBLED_MM`.

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
#: a single layer's neighbourhoods have a median kurtosis of 2.8-3.0 (Gaussian, sample of
#: 96); two layers' 1.3-2.1
BIMODAL_KURTOSIS = 2.4
#: two layers this far apart (90th percentile) are warned about: 3 mm read the girths up
#: to 1.2 mm wide on generated legs, 2 mm layers cannot be told from 1.4 mm of noise
DOUBLED_MM = 2.5


@dataclass(frozen=True)
class SkinLayers:
    """How thick a cloud's skin is: one layer or two (module docstring)."""

    median_kurtosis: float
    separation_p90_mm: float
    neighbourhoods: int

    @property
    def doubled(self) -> bool:
        return self.median_kurtosis < BIMODAL_KURTOSIS and self.separation_p90_mm >= DOUBLED_MM

    @property
    def doubled_text(self) -> str:
        """The fit's warning, in words."""
        return (f"the cloud holds the skin twice, about {self.separation_p90_mm:.0f} mm apart (two passes of the "
                "scanner exported without being merged, or the leg moved between them): the girths may read up to "
                f"{2 * self.separation_p90_mm:.0f} mm wide (the tape rides the outer layer); export the merged scan, "
                "or scan again standing still")


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
    _, axes = np.linalg.eigh(np.einsum("ski,skj->sij", local, local))  # ascending: the normal first
    u = np.einsum("ski,si->sk", local, axes[:, :, 2])
    v = np.einsum("ski,si->sk", local, axes[:, :, 1])
    h = np.einsum("ski,si->sk", local, axes[:, :, 0])
    design = np.stack([u * u, u * v, v * v, u, v, np.ones_like(u)], axis=-1)  # (s, k, 6)
    normal = np.einsum("ski,skj->sij", design, design) + 1e-9 * np.eye(6)
    coefficients = np.linalg.solve(normal, np.einsum("ski,sk->si", design, h)[..., None])[..., 0]
    residual = h - np.einsum("ski,si->sk", design, coefficients)
    m2 = np.mean(residual**2, axis=1)
    m4 = np.mean(residual**4, axis=1)
    kurtosis = m4 / np.maximum(m2**2, 1e-18)
    separation = 2.0 * np.clip((3.0 * m2**2 - m4) / 2.0, 0.0, None) ** 0.25
    return SkinLayers(float(np.median(kurtosis)), float(np.percentile(separation, 90)), len(seeds))
