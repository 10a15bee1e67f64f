"""Analytic test shapes (mm): tubes with a known cross-section and radius profile.

A tube is a closed triangulated surface: ``n_around`` vertices per ring, one ring per
height, capped at both ends so the mesh is watertight like a real scan.
"""

from __future__ import annotations

import numpy as np
import trimesh


def tube_mesh(heights: np.ndarray, radius_x: np.ndarray, radius_y: np.ndarray, n_around: int = 256) -> trimesh.Trimesh:
    """Elliptic rings of semi-axes (radius_x[k], radius_y[k]) at heights[k], capped."""
    theta = np.linspace(0.0, 2.0 * np.pi, n_around, endpoint=False)
    rings = np.stack(
        [
            radius_x[:, None] * np.cos(theta),
            radius_y[:, None] * np.sin(theta),
            np.broadcast_to(heights[:, None], (len(heights), n_around)),
        ],
        axis=-1,
    ).reshape(-1, 3)
    k = len(heights)
    i, j = np.meshgrid(np.arange(k - 1), np.arange(n_around), indexing="ij")
    a = i * n_around + j
    b = i * n_around + (j + 1) % n_around
    c = (i + 1) * n_around + (j + 1) % n_around
    d = (i + 1) * n_around + j
    side = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    bottom_centre, top_centre = len(rings), len(rings) + 1
    ring = np.arange(n_around)
    bottom = np.stack([np.full(n_around, bottom_centre), (ring + 1) % n_around, ring], -1)
    top = np.stack([np.full(n_around, top_centre), (k - 1) * n_around + ring, (k - 1) * n_around + (ring + 1) % n_around], -1)
    vertices = np.vstack([rings, [[0, 0, heights[0]], [0, 0, heights[-1]]]])
    return trimesh.Trimesh(vertices, np.vstack([side, bottom, top]), process=False)


def cylinder(radius_x: float, radius_y: float, length: float = 300.0, step: float = 1.0) -> trimesh.Trimesh:
    heights = np.arange(0.0, length + step / 2, step)
    return tube_mesh(heights, np.full(len(heights), radius_x), np.full(len(heights), radius_y))


def calf_radius(z: np.ndarray) -> np.ndarray:
    """A leg-like radius profile (mm): ankle waist near 80, calf bulge near 300, knee waist
    near 390, knee bulge and a foot/heel flare at the ends."""
    return (
        35.0
        + 25.0 * np.exp(-(((z - 300.0) / 90.0) ** 2))
        - 8.0 * np.exp(-(((z - 80.0) / 40.0) ** 2))
        + 12.0 * np.exp(-(((z - 450.0) / 50.0) ** 2))
        + 5.0 * np.exp(-((z / 40.0) ** 2))
    )


def revolution_leg(step: float = 1.0) -> trimesh.Trimesh:
    heights = np.arange(0.0, 450.0 + step / 2, step)
    r = calf_radius(heights)
    return tube_mesh(heights, r, r)


def revolution_truth(sigma_mm: float = 0.0) -> dict:
    """Landmark heights (z) and girths of :func:`calf_radius`, found numerically on a
    0.01 mm grid (girth = 2 pi r): B the ankle minimum, C the calf maximum, D the
    minimum above C, B1 the first height above B where the girth has risen half of the
    way to C's (app.geometry.anatomy.feature_layers.b1_height)."""
    z = np.arange(0.0, 450.0, 0.01)
    girth = 2.0 * np.pi * calf_radius(z)
    interior = (z > 40) & (z < 440)
    b = z[interior][np.argmin(np.where(z[interior] < 200, girth[interior], np.inf))]
    c = z[np.argmax(np.where((z > b) & (z < 400), girth, -np.inf))]
    d = z[np.argmin(np.where((z > c) & (z < 440), girth, np.inf))]
    g_b, g_c = 2.0 * np.pi * calf_radius(np.array([b, c]))
    b1 = z[np.argmax((z > b) & (z < c) & (girth >= 0.5 * (g_b + g_c)))]
    g = lambda h: float(2.0 * np.pi * calf_radius(np.array([h]))[0])  # noqa: E731
    return {"B": (b, g(b)), "B1": (b1, g(b1)), "C": (c, g(c)), "D": (d, g(d))}


#: the 7 layer heights of :func:`paper_tube`, mm
PAPER_TUBE_HEIGHTS = np.array([0.0, 40.0, 80.0, 130.0, 180.0, 230.0, 280.0])


def paper_tube(a: float, b: float, m: int = 72):
    """An elliptic tube as the paper's surface (7 layers x m points at
    :data:`PAPER_TUBE_HEIGHTS`), semi-axes a, b mm."""
    from app.geometry.spline.nurbs import surface_from_layers

    t = np.arange(m) * 2 * np.pi / m
    layers = np.stack([np.stack([a * np.cos(t), b * np.sin(t), np.full(m, z)], axis=1) for z in PAPER_TUBE_HEIGHTS])
    return surface_from_layers(layers)
