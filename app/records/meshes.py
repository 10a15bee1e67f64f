"""Tessellating a calf surface and writing it with trimesh (STL, GLB, glTF).

The tube is sampled on a (u, v) grid (u periodic around the leg, v from B to D), each
quad split into two triangles with outward normals, and mapped into the scan's own
coordinates and units with the record's frame so that it overlays the scan.  The
writers are trimesh's own (``trimesh.exchange``); nothing is written by hand.
"""

from __future__ import annotations

import trimesh

from app.geometry.spline.tessellation import apply_frame, surface_grid_faces, surface_mesh, tessellate

__all__ = ["EXPORT_FORMATS", "apply_frame", "export_mesh", "surface_grid_faces", "surface_mesh", "tessellate"]

EXPORT_FORMATS = {"stl": "stl", "glb": "glb", "gltf": "gltf"}


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
