"""Tessellating a calf surface and writing it with trimesh (STL, GLB, glTF).

The tube is sampled on a (u, v) grid (u periodic around the leg, v from B to D), each
quad split into two triangles with outward normals, and mapped into the scan's own
coordinates and units with the record's frame so that it overlays the scan.  The
writers are trimesh's own (``trimesh.exchange``); nothing is written by hand.
"""

from __future__ import annotations

import numpy as np
import trimesh

from app.geometry.nurbs import NurbsSurface, evaluate_grid

EXPORT_FORMATS = {"stl": "stl", "glb": "glb", "gltf": "gltf"}


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


def export_mesh(mesh: trimesh.Trimesh, file_format: str) -> bytes:
    """Serialize with trimesh: ``stl`` (binary), ``glb`` or ``gltf`` (embedded buffers)."""
    if file_format not in EXPORT_FORMATS:
        raise ValueError(f"unknown export format {file_format!r}")
    if file_format == "gltf":
        files = trimesh.Scene(mesh).export(file_type="gltf", embed_buffers=True)
        payload = files["model.gltf"] if isinstance(files, dict) else files
        return payload if isinstance(payload, bytes) else payload.encode()
    data = mesh.export(file_type=EXPORT_FORMATS[file_format])
    return data if isinstance(data, bytes) else str(data).encode()
