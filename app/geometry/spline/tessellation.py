"""Tessellation of a NURBS surface: a triangle grid over its (u, v) domain, and the
same as a trimesh mesh, optionally carried into the scan's frame (a 4x4 matrix).
Units: mm.
"""

from __future__ import annotations

import numpy as np
import trimesh

from app.geometry.spline.nurbs import NurbsSurface, evaluate_grid


def surface_grid_faces(n_u: int, n_v: int) -> np.ndarray:
    """(2 * n_u * (n_v - 1), 3) triangles of a u-periodic (n_u, n_v) vertex grid."""
    i, j = np.meshgrid(np.arange(n_u), np.arange(n_v - 1), indexing="ij")
    a = i * n_v + j
    b = ((i + 1) % n_u) * n_v + j
    c = ((i + 1) % n_u) * n_v + j + 1
    d = i * n_v + j + 1
    # counter-clockwise seen from outside for u running counter-clockwise about +z
    return np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])


def tessellate(surface: NurbsSurface, n_u: int = 144, n_v: int = 100) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n_u * n_v, 3) in calf-frame mm and faces of the surface tube."""
    u0, u1 = surface.domain_u
    v0, v1 = surface.domain_v
    u = u0 + (u1 - u0) * np.arange(n_u) / n_u
    v = np.linspace(v0, v1, n_v)
    vertices = evaluate_grid(surface, u, v).reshape(-1, 3)
    return vertices, surface_grid_faces(n_u, n_v)


def apply_frame(points: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Map (n, 3) calf-frame mm through the 4x4 ``frame`` into scan coordinates."""
    return points @ frame[:3, :3].T + frame[:3, 3]


def surface_mesh(surface: NurbsSurface, frame: np.ndarray | None = None, n_u: int = 144, n_v: int = 100) -> trimesh.Trimesh:
    """The tessellated surface as a trimesh, in scan coordinates if ``frame`` is given."""
    vertices, faces = tessellate(surface, n_u, n_v)
    if frame is not None:
        vertices = apply_frame(vertices, frame)
        if np.linalg.det(frame[:3, :3]) < 0:
            faces = faces[:, ::-1]
    return trimesh.Trimesh(vertices, faces, process=False)
