"""Hostile inputs, generated: each kind that once took the service down or answered 500
(issue 19), for the tests (tests/api/test_bounded_work.py) and the hostile-input
benchmark (benchmarks/hostile.py).  Nothing here is stored: every input is made on
demand from the vendored real leg or from numbers.
"""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import trimesh

LEG_STL = Path(__file__).resolve().parents[1] / "tests" / "data" / "real" / "bodyparts3d_right_leg.stl"


def tube_record(n_around: int, n_along: int, degree: int, radius_mm: float = 50.0, height_mm: float = 300.0,
                circumference_mm: float | None = None) -> dict:
    """A record body whose surface is a periodic tube: ``n_around`` distinct control
    columns (plus ``degree`` repeated), ``n_along`` rows, uniform knots, of the radius
    and height given (mm); landmarks at 5, 30, 60 and 95% of the height."""
    p = q = degree
    angle = 2 * np.pi * np.arange(n_around) / n_around
    nu = n_around + p
    ctrl = np.zeros((nu, n_along, 3))
    ctrl[:n_around, :, 0] = radius_mm * np.cos(angle)[:, None]
    ctrl[:n_around, :, 1] = radius_mm * np.sin(angle)[:, None]
    ctrl[:n_around, :, 2] = np.linspace(0.0, height_mm, n_along)[None, :]
    ctrl[n_around:] = ctrl[:p]
    knots_v = np.concatenate([np.zeros(q), np.linspace(0, 1, n_along - q + 1), np.ones(q)])
    girth = circumference_mm if circumference_mm is not None else max(2 * np.pi * radius_mm, 1.0)
    return {
        "schema_version": 2, "units": "mm", "side": "right",
        "surface": {"degree_u": p, "degree_v": q, "knots_u": np.arange(nu + p + 1, dtype=float).tolist(),
                    "knots_v": knots_v.tolist(), "control_points": ctrl.tolist(),
                    "weights": np.ones((nu, n_along)).tolist(), "periodic_u": True},
        "frame": np.eye(4).tolist(),
        "landmarks": {name: {"height_mm": share * height_mm, "circumference_mm": girth}
                      for name, share in zip(("B", "B1", "C", "D"), (0.05, 0.3, 0.6, 0.95))},
    }


def instanced_glb(copies: int, mesh: trimesh.Trimesh | None = None) -> bytes:
    """A GLB that stores ``mesh`` (the real leg by default) once and instances it from
    ``copies`` scene nodes: small on disk, ``copies`` times the triangles when expanded."""
    mesh = mesh if mesh is not None else trimesh.load(LEG_STL)
    scene = trimesh.Scene()
    scene.add_geometry(mesh, node_name="leg", geom_name="leg")
    glb = scene.export(file_type="glb")
    length, _ = struct.unpack_from("<II", glb, 12)
    document = json.loads(glb[20:20 + length])
    mesh_index = next(node["mesh"] for node in document["nodes"] if "mesh" in node)
    document["nodes"] = [{"mesh": mesh_index} for _ in range(copies)]
    document["scenes"] = [{"nodes": list(range(copies))}]
    document["scene"] = 0
    text = json.dumps(document).encode()
    text += b" " * (-len(text) % 4)
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + glb[20 + length:]
    return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


def leg_in_inches() -> bytes:
    """The real leg (mm) written in inches: its extent reads as centimetres."""
    leg = trimesh.load(LEG_STL)
    leg.apply_scale(1 / 25.4)
    return leg.export(file_type="stl")


def obj_with_2d_vertices(n: int = 600) -> bytes:
    """An OBJ whose vertices have two coordinates."""
    rng = np.random.default_rng(0)
    lines = [f"v {x:.3f} {y:.3f}" for x, y in rng.uniform(0, 300, (n, 2))]
    lines += [f"f {i} {i + 1} {i + 2}" for i in range(1, n - 2, 3)]
    return ("\n".join(lines) + "\n").encode()


def huge_coordinate_xyz(n: int = 600) -> bytes:
    """An XYZ cloud ``1e308 i 1e308`` for i = 0..n-1: finite coordinates whose spread
    overflows any sum of squares."""
    return "\n".join(f"1e308 {i} 1e308" for i in range(n)).encode()
