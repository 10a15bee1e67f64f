"""Scan clean-up before the leg is looked for: floor or platform, spikes, pieces.

Three steps, each a stated geometric rule (units mm; points (n, 3), faces (f, 3)):

1. **Floor or scanner platform** (:func:`find_floor`).  The dominant plane is found by
   RANSAC over a 20k-point stride sample: 256 fixed-seed triples, each a point and two of
   its 16 nearest neighbours (NAPSAC sampling, so that a plane holding a few percent of
   the points is still drawn; 16 keeps the triple on one face of a 40 mm platform),
   inliers within :data:`FLOOR_TOLERANCE_MM`; the best 8 planes are refined by least
   squares on their inliers three times (LO-RANSAC) and the one with most inliers kept.  It is a floor, not skin, when
   (a) its inliers spread at least :data:`FLOOR_MIN_WIDTH_MM` across their narrower
   in-plane axis - wider than any foot (ANSUR II's widest foot is 126 mm) and no patch of
   skin is that flat - and (b) at least a quarter of them lie in the open, more than
   :data:`FLOOR_MARGIN_MM` from the shadow (projection on the plane) of everything above
   it: a floor reaches past what stands on it; a flattened back or calf, or the flat soles
   of two feet side by side, lie in their own shadow; and
   (c) its normal lies within 45 degrees of the long axis of what stands more than the
   clearance above it (a floor is across a standing leg; the table under a lying body
   runs along it).  A platform's other face (a parallel plane within the clearance,
   holding at least half as many points) casts no shadow in (b).  Everything within the
   tolerance of the plane or beyond it is removed, and the search repeats (a platform
   shows its top and its bottom face), at most :data:`MAX_FLOORS` times.
2. **Spikes** (meshes, :func:`spike_faces`): needle triangles whose longest edge is over
   :data:`SPIKE_EDGE_FACTOR` times the median edge and over 20 mm, and whose area is
   under 5% of that edge squared, with a tip (a corner in at most two triangles).  Scanner streaks in point clouds are left to the robust
   polar fit (:mod:`app.geometry.sections.cloud`).
3. **Pieces**: a mesh's pieces are its connected components (vertices joined by faces;
   its vertex spacing varies too much for proximity); a point cloud's points are joined
   when they share or touch a voxel of :data:`VOXEL_FACTOR` times the median point
   spacing (at least 6 mm, :func:`voxel_pieces`).  Pieces with fewer than
   :data:`MIN_PIECE_FRACTION` of the points (stray points, dust) are dropped.
   Which of the rest are legs is decided by the leg search (a detached fragment has no
   ankle and knee).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

FLOOR_TOLERANCE_MM = 3.0
FLOOR_MIN_WIDTH_MM = 150.0
FLOOR_OUTSIDE_FRACTION = 0.25
FLOOR_CLEARANCE_MM = 60.0
#: a floor point this far (in the plane) from anything above the plane is in the open;
#: a point spacing of scanned skin is 1-10 mm, so a sole's points are all closer
FLOOR_MARGIN_MM = 30.0
MAX_FLOORS = 3
RANSAC_TRIALS = 256
RANSAC_SAMPLE = 20_000
RANSAC_NEIGHBOURS = 16
LO_CANDIDATES = 8
LO_STEPS = 3
SCORE_STRIDE = 5
SPIKE_EDGE_FACTOR = 10.0
VOXEL_FACTOR = 3.0
MIN_VOXEL_MM = 6.0
MIN_PIECE_FRACTION = 0.02


@dataclass(frozen=True)
class Floor:
    """A removed floor plane: unit ``normal`` (3,) pointing to the leg, a ``point`` (3,)
    on it, and how many scan points it took."""

    normal: np.ndarray
    point: np.ndarray
    n_removed: int


@dataclass(frozen=True)
class CleanScan:
    """A scan after clean-up: ``points`` (n, 3) mm, ``faces`` (f, 3) or None, ``pieces``
    (list of point-index arrays, largest first), what was removed (``floors``, the planes
    in the order they were removed; counts).  A point cloud's ``voxel_mm`` (the voxel its
    pieces were joined by) and ``spacing_p95_mm`` (95th percentile of its nearest-neighbour
    distances); None for a mesh.  :attr:`replay` repeats the clean-up exactly without
    searching again."""

    points: np.ndarray
    faces: np.ndarray | None
    pieces: list
    floors: tuple
    n_spike_faces: int
    n_stray_points: int
    voxel_mm: float | None = None
    spacing_p95_mm: float | None = None

    @property
    def floor(self) -> Floor | None:
        """The first plane removed, with the points of all of them (a platform shows its
        top and its bottom face); None when there was no floor."""
        if not self.floors:
            return None
        first = self.floors[0]
        return Floor(first.normal, first.point, sum(f.n_removed for f in self.floors))

    @property
    def replay(self) -> CleanupReplay:
        """What :func:`clean_scan` needs to repeat this clean-up on the same scan."""
        return CleanupReplay(tuple((f.point, f.normal) for f in self.floors), self.voxel_mm, self.spacing_p95_mm)


@dataclass(frozen=True)
class CleanupReplay:
    """What a clean-up found, to repeat it on the same scan: the floor planes
    ((point (3,), normal (3,)) pairs, scan mm), a cloud's voxel size and point spacing
    (mm, None for a mesh)."""

    floors: tuple = ()
    voxel_mm: float | None = None
    spacing_p95_mm: float | None = None

    def to_dict(self) -> dict:
        """JSON-ready (the keys of a stored placement)."""
        return {"floors": [[np.asarray(p).tolist(), np.asarray(n).tolist()] for p, n in self.floors],
                "voxel_mm": self.voxel_mm, "spacing_p95_mm": self.spacing_p95_mm}

    @classmethod
    def from_dict(cls, data: dict) -> CleanupReplay | None:
        """The replay in ``data`` (a stored placement), or None when it holds none."""
        if "floors" not in data and "voxel_mm" not in data:
            return None
        optional = lambda key: None if data.get(key) is None else float(data[key])  # noqa: E731
        return cls(tuple((np.asarray(p, dtype=float), np.asarray(n, dtype=float)) for p, n in data.get("floors", ())),
                   optional("voxel_mm"), optional("spacing_p95_mm"))


def _stride_sample(points: np.ndarray, count: int) -> np.ndarray:
    return points[:: max(len(points) // count, 1)]


def find_floor(points: np.ndarray) -> Floor | None:
    """The floor or platform plane under the scan, or None (rule 1 of the docstring)."""
    sample = _stride_sample(points, RANSAC_SAMPLE)
    if len(sample) < 100:
        return None
    rng = np.random.default_rng(0)
    # locally sampled triples (NAPSAC, Myatt et al. 2002): a random point and two of its
    # RANSAC_NEIGHBOURS nearest.  A triple then lies on the floor as often as its first
    # point does (a platform's top face holds ~13% of a cloud: uniform triples would hit
    # it 0.2% of the time, 256 local ones miss it with probability 1e-15)
    first = rng.integers(0, len(sample), size=RANSAC_TRIALS)
    _, near = cKDTree(sample).query(sample[first], k=RANSAC_NEIGHBOURS)
    pick = rng.integers(RANSAC_NEIGHBOURS // 2, RANSAC_NEIGHBOURS, size=(RANSAC_TRIALS, 2))
    triples = np.stack([sample[first], sample[near[np.arange(RANSAC_TRIALS), pick[:, 0]]],
                        sample[near[np.arange(RANSAC_TRIALS), pick[:, 1]]]], axis=1)
    normals = np.cross(triples[:, 1] - triples[:, 0], triples[:, 2] - triples[:, 0])
    norm = np.linalg.norm(normals, axis=1)
    good = norm > 1e-6
    normals = normals[good] / norm[good, None]
    offsets = np.einsum("kd,kd->k", normals, triples[good, 0])
    # hypotheses are scored on a fifth of the sample (a floor of 2% is still ~80 points
    # there); the best are refined on all of it
    scoring = sample[::SCORE_STRIDE]
    distance = np.abs(scoring @ normals.T - offsets)  # (s / 5, k)
    counts = (distance < FLOOR_TOLERANCE_MM).sum(axis=0)
    # local optimisation (LO-RANSAC, Chum et al. 2003) of the best few: a short baseline
    # tilts a plane by the noise; least-squares refits on its inliers take it to the
    # whole floor.  The refined plane with the most inliers wins.
    inliers = sample[:0]
    for k in np.argsort(-counts)[:LO_CANDIDATES]:
        candidate = scoring[distance[:, k] < FLOOR_TOLERANCE_MM]
        for _ in range(LO_STEPS):
            if len(candidate) < 3:
                break
            centre = candidate.mean(axis=0)
            normal = np.linalg.svd(candidate - centre, full_matrices=False)[2][2]
            candidate = sample[np.abs((sample - centre) @ normal) < FLOOR_TOLERANCE_MM]
        if len(candidate) > len(inliers):
            inliers = candidate
    if len(inliers) < 0.02 * len(sample):
        return None
    centre = inliers.mean(axis=0)
    _, _, vt = np.linalg.svd(inliers - centre, full_matrices=False)
    normal = vt[2]
    signed = (sample - centre) @ normal
    on_plane = np.abs(signed) < FLOOR_TOLERANCE_MM
    if (~on_plane).sum() < 100:
        return None
    if np.median(signed[~on_plane]) < 0:
        normal, signed = -normal, -signed
    rest = sample[signed > FLOOR_CLEARANCE_MM]
    if len(rest) < 100:
        return None
    # (c) a floor is across what stands on it: its normal lies within 45 degrees of the
    # long axis of what stands above the clearance (a table under a lying body is along
    # it).  Not of everything off the plane: a platform's other face, 40 mm away and as
    # large as this one, would set the axis.
    centred = rest - rest.mean(axis=0)
    long_axis = np.linalg.eigh(centred.T @ centred)[1][:, -1]
    if abs(long_axis @ normal) < np.cos(np.radians(45.0)):
        return None
    in_plane = np.stack([vt[0], vt[1]])
    flat = (sample[on_plane] - centre) @ in_plane.T
    spread = np.percentile(flat, 97.5, axis=0) - np.percentile(flat, 2.5, axis=0)
    if spread.min() < FLOOR_MIN_WIDTH_MM:
        return None
    # (b) the floor reaches past what stands on it: its points lie in the open, more than
    # FLOOR_MARGIN_MM from the shadow (the projection on the plane) of everything above
    # it.  The flat soles of two feet side by side lie under their own feet, in the
    # shadow: they are skin, not a floor.
    # a platform's other face - parallel, within the clearance, about as large - does not
    # stand on this one: when the plane is a platform's bottom face, its top face would
    # otherwise cast a shadow over all of it
    above = signed >= FLOOR_TOLERANCE_MM
    near = signed[above & (signed <= FLOOR_CLEARANCE_MM)]
    if len(near):
        bins = np.bincount(np.floor(near).astype(np.int64))
        peak = float(np.argmax(np.convolve(bins, np.ones(int(2 * FLOOR_TOLERANCE_MM)), mode="same"))) + 0.5
        twin = np.abs(signed - peak) < FLOOR_TOLERANCE_MM
        if twin.sum() >= 0.5 * on_plane.sum():
            above &= ~twin
    shadow = (sample[above] - centre) @ in_plane.T
    gap, _ = cKDTree(shadow).query(flat, distance_upper_bound=FLOOR_MARGIN_MM)
    outside = float(np.mean(~np.isfinite(gap)))
    if outside < FLOOR_OUTSIDE_FRACTION:
        return None
    removed = int(((points - centre) @ normal < FLOOR_TOLERANCE_MM).sum())
    return Floor(normal, centre, removed)


def spike_faces(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """(f,) bool: needle triangles sticking out of the skin (rule 2 of the docstring).
    Only the triangles with an edge over the limit are tested further (area, tip)."""
    a, b, c = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    edges = np.stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1)], 1)
    longest = edges.max(axis=1)
    limit = max(SPIKE_EDGE_FACTOR * float(np.median(edges)), 20.0)
    needle = np.zeros(len(faces), dtype=bool)
    long = np.flatnonzero(longest > limit)
    if long.size == 0:
        return needle
    area = 0.5 * np.linalg.norm(np.cross(b[long] - a[long], c[long] - a[long]), axis=1)
    thin = long[area < 0.05 * longest[long] ** 2]
    # and it sticks out: one of its corners belongs to at most two triangles (a tip), not
    # a sliver inside a closed surface
    degree = np.bincount(faces.ravel(), minlength=len(points))
    needle[thin[degree[faces[thin]].min(axis=1) <= 2]] = True
    return needle


def neighbour_distances(points: np.ndarray) -> np.ndarray:
    """Nearest-neighbour distances (s,) of a 5k-point stride sample of points (n, 3), mm."""
    sample = _stride_sample(points, 5000)
    # an unbalanced, non-compacted tree builds twice as fast and queries as fast here
    distance, _ = cKDTree(points, balanced_tree=False, compact_nodes=False).query(sample, k=2)
    return distance[:, 1]


def point_spacing(points: np.ndarray, percentile: float = 50.0) -> float:
    """Nearest-neighbour distance (median, or another percentile) of a 5k-point stride
    sample, mm."""
    return float(np.percentile(neighbour_distances(points), percentile))


#: the voxel grows while the pieces too small to keep hold more than this share of a
#: cloud's points; by this factor a step, up to MAX_VOXEL_MM
SCATTERED_SHARE = 0.05
VOXEL_GROWTH = 1.5
MAX_VOXEL_MM = 30.0


def joining_voxel(points: np.ndarray, voxel_mm: float) -> tuple[float, np.ndarray]:
    """The voxel (mm) that joins a cloud's skin into pieces, from the first guess
    ``voxel_mm`` (3 x the median spacing), and the (n,) piece labels it gives.

    The median nearest-neighbour spacing sees the points along a scanner's rings, not the
    gaps between the rings: the vertices of a coarse mesh exported as a cloud lie 3-5 mm
    apart on a ring and 10-20 mm between rings, and the first voxel breaks the shin into
    ring fragments that are then dropped as dust, or a body into pieces.  Dust is a few
    per cent of a scan (the corpus' stray points: 2%); so while the pieces under
    :data:`MIN_PIECE_FRACTION` hold more than :data:`SCATTERED_SHARE` of the points, or
    a voxel :data:`VOXEL_GROWTH` times larger joins two kept pieces (one subject broken
    at a gap between its rings, often bridged by ring fragments; a detached fragment or
    the other leg of a feet-to-knee scan stands further off), the voxel grows by that
    factor, up to :data:`MAX_VOXEL_MM` (the coarsest spacing the service fits).  points
    (n, 3) mm.
    """
    labels = voxel_pieces(points, voxel_mm)
    while voxel_mm < MAX_VOXEL_MM:
        sizes = np.bincount(labels)
        kept = int((sizes >= MIN_PIECE_FRACTION * len(points)).sum())
        scattered = sizes[sizes < MIN_PIECE_FRACTION * len(points)].sum() > SCATTERED_SHARE * len(points)
        larger = min(voxel_mm * VOXEL_GROWTH, MAX_VOXEL_MM)
        grown = voxel_pieces(points, larger)
        grown_sizes = np.bincount(grown)
        merged = int((grown_sizes >= MIN_PIECE_FRACTION * len(points)).sum()) < kept
        if not (scattered or merged):
            break
        voxel_mm, labels = larger, grown
    return voxel_mm, labels


def voxel_pieces(points: np.ndarray, voxel_mm: float) -> np.ndarray:
    """(n,) piece label of every point: points in the same or touching voxels (26
    neighbours) are joined.  Sparse: only occupied voxels are kept (no dense grid)."""
    cells = np.floor((points - points.min(axis=0)) / voxel_mm).astype(np.int64)
    dims = cells.max(axis=0) + 3
    key = ((cells[:, 0] + 1) * dims[1] + cells[:, 1] + 1) * dims[2] + cells[:, 2] + 1
    unique, inverse = np.unique(key, return_inverse=True)
    rows, cols = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if (dx, dy, dz) <= (0, 0, 0):
                    continue  # each neighbour pair once
                neighbour = unique + (dx * dims[1] + dy) * dims[2] + dz
                at = np.searchsorted(unique, neighbour)
                at = np.minimum(at, len(unique) - 1)
                hit = unique[at] == neighbour
                rows.append(np.flatnonzero(hit))
                cols.append(at[hit])
    row_index, col_index = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(row_index), dtype=np.int8), (row_index, col_index)), shape=(len(unique), len(unique)))
    _, labels = connected_components(graph, directed=False)
    return labels[inverse.reshape(-1)]


def clean_scan(points: np.ndarray, faces: np.ndarray | None, replay: CleanupReplay | None = None) -> CleanScan:
    """Floor, spikes and stray pieces removed; the remaining pieces listed (docstring).

    ``replay``: what an earlier clean-up of the same scan found (its floor planes and
    voxel size), applied as they are instead of being searched for; the result is the
    same."""
    keep = np.ones(len(points), dtype=bool)
    floors: list[Floor] = []
    for attempt in range(MAX_FLOORS if replay is None else len(replay.floors)):
        if replay is None:
            found = find_floor(points[keep])
            if found is None:
                break
            point, normal = found.point, found.normal
        else:
            point, normal = (np.asarray(x, dtype=float) for x in replay.floors[attempt])
        above = (points - point) @ normal >= FLOOR_TOLERANCE_MM
        floors.append(Floor(normal, point, int((keep & ~above).sum())))
        keep &= above
    n_spikes = 0
    spacing_p95 = None
    if faces is not None:
        spikes = spike_faces(points, faces)
        n_spikes = int(spikes.sum())
        faces = faces[~spikes & keep[faces].all(axis=1)]
        used = np.zeros(len(points), dtype=bool)
        used[faces.ravel()] = True
        keep &= used
    index = np.flatnonzero(keep)
    kept = points[index]
    if faces is not None:
        remap = np.full(len(points), -1, dtype=np.int64)
        remap[index] = np.arange(len(index))
        f = remap[faces]
        edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]]])
        graph = coo_matrix((np.ones(len(edges), dtype=np.int8), (edges[:, 0], edges[:, 1])), shape=(len(index),) * 2)
        labels = connected_components(graph, directed=False)[1]
    else:
        if replay is not None and replay.voxel_mm is not None:
            voxel_mm = float(replay.voxel_mm)
            spacing_p95 = replay.spacing_p95_mm
            labels = voxel_pieces(kept, voxel_mm)
        else:
            spacing = neighbour_distances(kept)
            voxel_mm = max(VOXEL_FACTOR * float(np.median(spacing)), MIN_VOXEL_MM)
            spacing_p95 = float(np.percentile(spacing, 95.0))
            voxel_mm, labels = joining_voxel(kept, voxel_mm)
    sizes = np.bincount(labels)
    big = np.flatnonzero(sizes >= MIN_PIECE_FRACTION * len(kept))
    big = big[np.argsort(-sizes[big])]
    in_piece = np.isin(labels, big)
    # renumber the kept points and their faces
    final = index[in_piece]
    remap = np.full(len(points), -1, dtype=np.int64)
    remap[final] = np.arange(len(final))
    new_faces = None
    if faces is not None:
        mapped = remap[faces]
        new_faces = mapped[(mapped >= 0).all(axis=1)]
    # the points of each piece, largest first: one stable sort, split at the run ends
    rank = np.empty(labels.max() + 1, dtype=np.int64)
    rank[big] = np.arange(len(big))
    order = np.argsort(rank[labels[in_piece]], kind="stable")
    pieces = np.split(order, np.cumsum(sizes[big])[:-1])
    return CleanScan(points[final], new_faces, pieces, tuple(floors), n_spikes, int((~in_piece).sum()),
                     None if faces is not None else voxel_mm, spacing_p95)
