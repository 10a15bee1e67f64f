"""A population of calves: the average calf, its main modes of variation, girth percentiles.

Lsq records on one grid correspond control point to control point (:mod:`app.geometry.spline.lsq`:
u = 0 anterior, B, B1, C, D at v = 0, 1/3, 2/3, 1, the same knot vectors), so the calves
of many people are points in one space of nets (around x along x 3 numbers) and the
statistics are those of a point distribution model (Cootes et al., 1995):

- the average calf is the mean net (a B-spline is linear in its control points: the
  mean net is the surface whose points are the means of the corresponding points);
- the modes of variation are the principal components of the centred nets (SVD), each
  with its share of the total variance and its standard deviation as the RMS movement
  of the control points (mm);
- left legs are mirrored into right legs first (x -> -x, and u -> -u so that u still
  runs counter-clockwise from the front), so a population may mix both sides.

Nets are (around, along, 3) arrays of distinct control columns, mm, calf frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.spline.lsq import DEGREE
from app.geometry.spline.nurbs import NurbsSurface

PERCENTILES = (5, 25, 50, 75, 95)
MAX_MODES = 5


def distinct_net(surface: NurbsSurface) -> np.ndarray:
    """(around, along, 3): the control columns of a periodic surface without the repeats."""
    return surface.control_points[: surface.shape[0] - DEGREE]


def as_right_leg(net: np.ndarray) -> np.ndarray:
    """The net of the mirror image (x -> -x) with u reversed about the front (column 0)."""
    around = net.shape[0]
    return net[(-np.arange(around)) % around] * np.array([-1.0, 1.0, 1.0])


@dataclass(frozen=True)
class Population:
    """mean_net (around, along, 3) mm; modes (k, around, along, 3) unit vectors;
    variance_share (k,) of the total; sd_mm (k,) RMS control point movement of 1 sd."""

    n: int
    mean_net: np.ndarray
    modes: np.ndarray
    variance_share: np.ndarray
    sd_mm: np.ndarray


def population_of(nets: np.ndarray, max_modes: int = MAX_MODES) -> Population:
    """The point distribution model of nets (N, around, along, 3), N >= 1."""
    n = len(nets)
    flat = nets.reshape(n, -1)
    mean = flat.mean(axis=0)
    if n < 2:
        empty = np.zeros((0,) + nets.shape[1:])
        return Population(n, mean.reshape(nets.shape[1:]), empty, np.zeros(0), np.zeros(0))
    _, singular, vt = np.linalg.svd(flat - mean, full_matrices=False)
    variance = singular**2 / (n - 1)
    total = variance.sum()
    # modes with a variance above round-off (relative to the squared size of the calf)
    k = min(max_modes, n - 1, int((variance > 1e-20 * float(np.mean(flat**2))).sum()))
    share = variance[:k] / total if total > 0 else np.zeros(k)
    # 1 sd along a mode moves the control points by sqrt(variance) in total: RMS per point
    sd = np.sqrt(variance[:k] / (flat.shape[1] // 3))
    return Population(n, mean.reshape(nets.shape[1:]), vt[:k].reshape((k,) + nets.shape[1:]), share, sd)


def girth_percentiles(girths: dict[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """name -> {"p5": ..., "p25": ..., ...} of the girths (N,) mm at each landmark."""
    return {name: {f"p{p}": float(np.percentile(values, p)) for p in PERCENTILES} for name, values in girths.items()}
