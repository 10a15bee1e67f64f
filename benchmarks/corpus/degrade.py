"""Degradations that real scanners and real clinics produce, applied to a clean leg.

Every function takes and returns millimetre geometry in the generating coordinates
(MakeHuman axes: Y up, +Z anterior) and draws its randomness from the ``rng`` given,
so a case is reproducible from its seed.  Meshes are ``trimesh.Trimesh``; point clouds
(n, 3) float64 arrays.
"""

from __future__ import annotations

import numpy as np
import trimesh


def crop(mesh: trimesh.Trimesh, point: np.ndarray, normal: np.ndarray) -> trimesh.Trimesh:
    """Keep the part of ``mesh`` on the ``normal`` side of the plane through ``point``
    (an exact plane cut, as a scanner's crop box makes; left open)."""
    vertices, faces = trimesh.intersections.slice_faces_plane(
        mesh.vertices, mesh.faces, normal / np.linalg.norm(normal), point)[:2]
    out = trimesh.Trimesh(vertices, faces, process=False)
    out.remove_unreferenced_vertices()
    return out


def tilted(axis: np.ndarray, max_deg: float, rng: np.random.Generator) -> np.ndarray:
    """``axis`` (3,) turned by up to ``max_deg`` degrees in a random direction."""
    other = rng.normal(size=3)
    other -= (other @ axis) * axis
    other /= np.linalg.norm(other)
    angle = np.radians(rng.uniform(0.0, max_deg))
    return np.cos(angle) * axis + np.sin(angle) * other


def punch_holes(mesh: trimesh.Trimesh, centres: np.ndarray, radius_mm: np.ndarray) -> trimesh.Trimesh:
    """Remove the faces whose centroid lies within ``radius_mm`` (h,) of ``centres`` (h, 3)."""
    c = mesh.triangles_center
    gone = np.zeros(len(c), dtype=bool)
    for centre, radius in zip(centres, radius_mm):
        gone |= np.linalg.norm(c - centre, axis=1) < radius
    out = trimesh.Trimesh(mesh.vertices, mesh.faces[~gone], process=False)
    out.remove_unreferenced_vertices()
    return out


def holes_on_calf(mesh: trimesh.Trimesh, low: np.ndarray, high: np.ndarray, count: int,
                  rng: np.random.Generator, max_across_mm: float = 40.0) -> tuple[np.ndarray, np.ndarray]:
    """Random hole centres on the surface between the points ``low`` and ``high`` along
    the leg, and radii up to ``max_across_mm / 2``: (count, 3), (count,)."""
    axis = (high - low) / np.linalg.norm(high - low)
    t = (mesh.vertices - low) @ axis
    candidates = np.flatnonzero((t > 0) & (t < np.linalg.norm(high - low)))
    centres = mesh.vertices[rng.choice(candidates, size=count, replace=False)]
    return centres, rng.uniform(0.3, 0.5, size=count) * max_across_mm


def vertex_noise(mesh: trimesh.Trimesh, sigma_mm: float, rng: np.random.Generator) -> trimesh.Trimesh:
    """Gaussian noise of ``sigma_mm`` along each vertex normal (a scanner's depth noise)."""
    normals = mesh.vertex_normals
    moved = mesh.vertices + normals * rng.normal(0.0, sigma_mm, size=(len(normals), 1))
    return trimesh.Trimesh(moved, mesh.faces, process=False)


#: the swelling spares the sole: skin whose normal points further down the shank axis
#: than this cosine (the sole's, which bears the weight and does not swell outwards)
SOLE_NORMAL_COS = -0.7


def swell_lower_leg(mesh: trimesh.Trimesh, ankle_mm: np.ndarray, knee_mm: np.ndarray, swelling_mm: float,
                    reach: float) -> trimesh.Trimesh:
    """An oedematous (lymphoedematous) lower leg: the skin moved out along its normals by
    ``swelling_mm`` over the foot and the ankle (up to 20 mm above the ankle joint),
    fading as a half cosine to none at ``reach`` (0..1) of the way from the ankle joint
    to the knee joint; the sole stays (SOLE_NORMAL_COS).  Swelling of venous disease and
    lymphoedema is greatest at the foot and ankle and fades up the leg, so the ankle
    widens towards the calf and the knee waist: the calf's bulge over the ankle C/B falls
    from ANSUR II's 1.40-2.3 towards 1, and a swollen ankle can be wider than the knee
    waist.  ``ankle_mm``, ``knee_mm`` (3,) the joints, mm."""
    axis = (knee_mm - ankle_mm) / np.linalg.norm(knee_mm - ankle_mm)
    shank = float(np.linalg.norm(knee_mm - ankle_mm))
    height = (mesh.vertices - ankle_mm) @ axis
    fade = np.clip((height - 20.0) / max(reach * shank - 20.0, 1.0), 0.0, 1.0)
    normals = mesh.vertex_normals
    weight = 0.5 * (1.0 + np.cos(np.pi * fade)) * (normals @ axis > SOLE_NORMAL_COS)
    return trimesh.Trimesh(mesh.vertices + (swelling_mm * weight)[:, None] * normals, mesh.faces, process=False)


def sample_cloud(mesh: trimesh.Trimesh, count: int, rng: np.random.Generator) -> np.ndarray:
    """(count, 3) points drawn uniformly by area from the surface."""
    points, _ = trimesh.sample.sample_surface(mesh, count, seed=int(rng.integers(2**31)))
    return np.asarray(points)


def moved_scan_file(mesh: trimesh.Trimesh, motion: np.ndarray, as_cloud: bool, rng: np.random.Generator,
                    cloud_points: int = 80_000) -> tuple[bytes, str]:
    """The scan file of ``mesh`` moved by ``motion`` (4, 4): a binary STL, or with
    ``as_cloud`` a PLY of ``cloud_points`` points drawn from its surface (the mesh is left
    as it was only for a cloud: a mesh is moved in place)."""
    if as_cloud:
        points = trimesh.transform_points(sample_cloud(mesh, cloud_points, rng), motion)
        return trimesh.PointCloud(points).export(file_type="ply"), "ply"
    mesh.apply_transform(motion)
    return mesh.export(file_type="stl"), "stl"


def cloud_noise(points: np.ndarray, sigma_mm: float, rng: np.random.Generator) -> np.ndarray:
    """Isotropic Gaussian noise of ``sigma_mm`` per coordinate."""
    return points + rng.normal(0.0, sigma_mm, size=points.shape)


def uneven_density(points: np.ndarray, axis: np.ndarray, rng: np.random.Generator, keep: float = 0.25) -> np.ndarray:
    """One side of the leg (a random direction across ``axis``) sampled 1/keep times sparser."""
    centre = points.mean(axis=0)
    side = tilted(axis, 90.0, rng)
    side -= (side @ axis) * axis
    far = (points - centre) @ side > 0
    return points[~far | (rng.random(len(points)) < keep)]


def cloud_holes(points: np.ndarray, centres: np.ndarray, radius_mm: np.ndarray) -> np.ndarray:
    gone = np.zeros(len(points), dtype=bool)
    for centre, radius in zip(centres, radius_mm):
        gone |= np.linalg.norm(points - centre, axis=1) < radius
    return points[~gone]


def outliers(points: np.ndarray, fraction: float, floor_y: float, rng: np.random.Generator) -> np.ndarray:
    """Add ``fraction`` stray points: a third uniform in the box around the leg, a third
    floor points around the feet, a third just off the skin (5-40 mm; scanner ghosts)."""
    n = max(int(fraction * len(points)), 3)
    lo, hi = points.min(axis=0) - 60.0, points.max(axis=0) + 60.0
    box = rng.uniform(lo, hi, size=(n // 3, 3))
    floor = rng.uniform(lo, hi, size=(n // 3, 3))
    floor[:, 1] = floor_y + rng.normal(0, 1.0, n // 3)
    near = points[rng.choice(len(points), n - 2 * (n // 3))]
    offset = rng.normal(size=near.shape)
    offset /= np.linalg.norm(offset, axis=1, keepdims=True)
    near = near + offset * rng.uniform(5.0, 40.0, size=(len(near), 1))
    return np.vstack([points, box, floor, near])


def floor_plane(centre: np.ndarray, floor_y: float, size_mm: float, rng: np.random.Generator,
                as_box: bool) -> trimesh.Trimesh:
    """A floor (a 10 mm grid of triangles) or a scanner platform (a box) whose top is at
    ``floor_y``, centred under ``centre`` (mm)."""
    if as_box:
        box = trimesh.creation.box(extents=(size_mm, 40.0, size_mm))
        box.apply_translation([centre[0], floor_y - 20.0, centre[2]])
        return box
    n = int(size_mm // 10)
    g = np.linspace(-size_mm / 2, size_mm / 2, n + 1)
    xx, zz = np.meshgrid(g + centre[0], g + centre[2], indexing="ij")
    vertices = np.column_stack([xx.ravel(), np.full(xx.size, floor_y), zz.ravel()])
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    b, c, d = a + 1, a + n + 2, a + n + 1
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return trimesh.Trimesh(vertices, faces, process=False)


def spikes(mesh: trimesh.Trimesh, count: int, rng: np.random.Generator) -> trimesh.Trimesh:
    """Needle triangles 30-80 mm long sticking out of the skin (reflections, hair)."""
    index = rng.choice(len(mesh.vertices), size=count, replace=False)
    base = mesh.vertices[index]
    normals = mesh.vertex_normals[index]
    tip = base + normals * rng.uniform(30.0, 80.0, size=(count, 1))
    side = base + np.cross(normals, [0.0, 1.0, 0.0]) * 1.0
    n0 = len(mesh.vertices)
    vertices = np.vstack([mesh.vertices, tip, side])
    faces = np.column_stack([index, n0 + np.arange(count), n0 + count + np.arange(count)])
    return trimesh.Trimesh(vertices, np.vstack([mesh.faces, faces]), process=False)


def cloud_spikes(points: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """Lines of points 30-80 mm long leaving the surface outwards (scanner streaks)."""
    centre = points.mean(axis=0)
    base = points[rng.choice(len(points), size=count)]
    out = base - centre
    out[:, 1] = 0.0
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    t = rng.uniform(0.0, 1.0, size=(count, 40, 1)) * rng.uniform(30.0, 80.0, size=(count, 1, 1))
    return np.vstack([points, (base[:, None] + out[:, None] * t).reshape(-1, 3)])


def rigid_motion(rng: np.random.Generator) -> np.ndarray:
    """A random 4x4 rotation (uniform on SO(3)) and translation of up to 1 m."""
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    m = trimesh.transformations.quaternion_matrix(q)
    m[:3, 3] = rng.uniform(-1000.0, 1000.0, size=3)
    return m


def coarsen(vertices: np.ndarray, faces: np.ndarray, cell_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """A coarser tessellation of a mesh by vertex clustering: the vertices in each
    ``cell_mm`` cube become their mean, triangles that collapse are dropped (what a
    scanner's low-resolution export or a registered body template looks like: edges of
    about 1-1.5 cells).  vertices (n, 3) mm, faces (f, 3); returns the new pair."""
    key = np.floor(vertices / cell_mm).astype(np.int64)
    _, cluster = np.unique(key, axis=0, return_inverse=True)
    cluster = cluster.ravel()
    merged = np.zeros((cluster.max() + 1, 3))
    np.add.at(merged, cluster, vertices)
    merged /= np.bincount(cluster)[:, None]
    new_faces = cluster[faces]
    keep = (new_faces[:, 0] != new_faces[:, 1]) & (new_faces[:, 1] != new_faces[:, 2]) & (new_faces[:, 0] != new_faces[:, 2])
    return merged, new_faces[keep]
