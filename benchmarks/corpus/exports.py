"""What exporters and mesh tools do to a scan before a clinic uploads it: a fixed
precision, a wall for 3D printing, closed ends, two-sided or mixed windings.

Every function takes and returns a ``trimesh.Trimesh`` in millimetres (the generating
coordinates of benchmarks/corpus; vertices merged, so that a boundary is a loop) and
draws nothing at random unless it takes an ``rng``.
"""

from __future__ import annotations

import numpy as np
import trimesh


def rounded_to_grid(mesh: trimesh.Trimesh, cell_mm: float) -> trimesh.Trimesh:
    """The mesh with every vertex rounded to a ``cell_mm`` grid (an exporter writing fixed
    decimals, Draco's quantisation): triangles collapse to segments and points, and are
    kept as the file would keep them."""
    return trimesh.Trimesh(np.round(mesh.vertices / cell_mm) * cell_mm, mesh.faces, process=False)


def boundary_loops(mesh: trimesh.Trimesh) -> list[np.ndarray]:
    """The mesh's open boundaries as vertex-index loops (each (m,), m > 8), in the order
    the faces run along them."""
    faces = np.asarray(mesh.faces)
    edges = np.vstack([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    _, inverse, count = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True, return_counts=True)
    border = edges[count[inverse.ravel()] == 1]
    following = dict(zip(border[:, 0].tolist(), border[:, 1].tolist()))
    loops, seen = [], set()
    for start in list(following):  # a few loops of a few hundred edges: a walk, not a point loop
        if start in seen:
            continue
        loop, vertex = [start], following[start]
        seen.add(start)
        while vertex != start and vertex in following and vertex not in seen:
            loop.append(vertex)
            seen.add(vertex)
            vertex = following[vertex]
        if len(loop) > 8:
            loops.append(np.array(loop))
    return loops


def hollowed(mesh: trimesh.Trimesh, wall_mm: float, rims: bool) -> trimesh.Trimesh:
    """The mesh given a wall ``wall_mm`` thick inward along its vertex normals (a
    solidify, a shell hollowed for 3D printing); with ``rims`` the two surfaces are joined
    along every open boundary (one connected surface), else the inner one is a piece of
    its own."""
    n = len(mesh.vertices)
    vertices = np.vstack([mesh.vertices, mesh.vertices - wall_mm * mesh.vertex_normals])
    faces = [np.asarray(mesh.faces), np.asarray(mesh.faces)[:, ::-1] + n]
    if rims:
        for loop in boundary_loops(mesh):
            ahead = np.roll(loop, -1)
            faces += [np.column_stack([ahead, loop, loop + n]), np.column_stack([ahead, loop + n, ahead + n])]
    return trimesh.Trimesh(vertices, np.vstack(faces), process=False)


#: a cap's height over its boundary, as a share of the boundary's mean radius
CAP_HEIGHTS = {"flat": 0.0, "low_dome": 0.25, "dome": 0.6}


def capped(mesh: trimesh.Trimesh, style: str) -> trimesh.Trimesh:
    """The mesh with every open boundary closed (a "watertight" export): a flat fan, or a
    dome of :data:`CAP_HEIGHTS` [``style``] times the boundary's mean radius over its plane
    (a Poisson or hole-filling closure), rising away from the mesh."""
    parts = [mesh]
    middle = mesh.vertices.mean(axis=0)
    for loop in boundary_loops(mesh):
        ring = mesh.vertices[loop[::-1]]  # the cap runs its boundary the other way: one winding
        centre = ring.mean(axis=0)
        normal = np.linalg.svd(ring - centre)[2][2]
        normal = normal if (centre - middle) @ normal > 0 else -normal
        radius = float(np.linalg.norm(ring - centre, axis=1).mean())
        height = CAP_HEIGHTS[style] * radius
        rings = 1 if height == 0 else 8
        phi = 0.5 * np.pi * np.arange(rings) / rings
        stack = centre + (ring - centre)[None] * np.cos(phi)[:, None, None] + (height * np.sin(phi))[:, None, None] * normal
        k = len(ring)
        vertices = np.vstack([stack.reshape(-1, 3), centre + height * normal])
        around = np.arange(k)
        faces = []
        for level in range(rings - 1):
            a, b = level * k + around, level * k + (around + 1) % k
            faces += [np.column_stack([a, b, b + k]), np.column_stack([a, b + k, a + k])]
        top = (rings - 1) * k
        faces.append(np.column_stack([top + around, top + (around + 1) % k, np.full(k, len(vertices) - 1)]))
        parts.append(trimesh.Trimesh(vertices, np.vstack(faces), process=False))
    return trimesh.util.concatenate(parts)


def double_sided(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """Every face twice, once each way round (a two-sided export)."""
    return trimesh.Trimesh(mesh.vertices, np.vstack([mesh.faces, mesh.faces[:, ::-1]]), process=False)


def windings_mixed(mesh: trimesh.Trimesh, rng: np.random.Generator) -> trimesh.Trimesh:
    """Half the faces, drawn at random, wound the other way (inconsistent normals)."""
    flip = rng.random(len(mesh.faces)) < 0.5
    return trimesh.Trimesh(mesh.vertices, np.where(flip[:, None], mesh.faces[:, ::-1], mesh.faces), process=False)
