"""Bent legs: the straight runs of a leg's centre line, and the shank cut free of the
thigh at the knee.

A leg scanned seated has its knee bent by up to 100 degrees.  Its principal axis is then
the body's, not the shank's, and near the knee the planes perpendicular to the shank
reach into the thigh, so their contours are the shank's and the thigh's together.  This
module finds the shank's own axis and the half-spaces that keep only the shank:

1. the centre line (centroids of :data:`CENTRE_LINE_BIN_MM` bins along the main axis) is
   split where it bends (Douglas-Peucker: a run is straight when no centroid lies more
   than :data:`BEND_TOLERANCE_MM` off its chord); runs of a lower leg's length or more
   are the shank and the thigh;
2. a run with a long neighbour (short runs between them are the bend) is cut at the
   joint between them (the knee: where their centre lines come closest) by the plane
   bisecting the knee angle (normal ``u_run + u_next``, both unit vectors pointing along
   the centre line away from the run's other end): what lies beyond it is the thigh;
3. the sections that plane crosses near the knee lose the rays it cut off; like holes,
   those are filled by the polar interpolation of the section (paper section 2.1).
   (Cutting the shank perpendicular where the plane first meets its skin was tried and
   rejected: at 30-70 degrees that is at or below the knee waist, so measurable knee
   waists were refused.)

Binned along the main axis, the centre line of a leg bent by 80-100 degrees follows
neither limb: the main axis is then the L's diagonal, and each bin's centroid is the mean
of a piece of shank and a piece of thigh.  When no run of that line places a calf,
:func:`geodesic_shank_runs` bins the surface by its distance *along the surface* from
one end of the leg instead (level sets of the geodesic distance are the limb's cross
sections whatever its bend: Lazarus and Verroust, "Level set diagrams of polyhedral
objects", ACM Solid Modeling 1999), measured on the graph of each sample's nearest
neighbours (scipy.sparse.csgraph.dijkstra), and splits that line the same way: to tell
why such a leg is refused (:func:`seated_knee_refusals`), never to measure it.

Units: mm; points (n, 3) in the scan's mm frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from app.geometry.anatomy.landmark_refusals import SCAN_STRAIGHT
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.placement.calf_frame import angle_deg, principal_axis

#: centre-line bins along the leg, and the straightness tolerance of a run, mm
CENTRE_LINE_BIN_MM = 15.0
BEND_TOLERANCE_MM = 25.0
#: a run at least this long is a shank or a thigh (ANSUR II: lateral malleolus to
#: tibiale is at least ~300 mm), mm
MIN_RUN_MM = 200.0
#: bends smaller than this are a straight leg (a 10 degree bend moves the knee plane by
#: R tan 5 deg ~ 5 mm at the shank's surface; a standing leg is never cut), degrees
MIN_FLEXION_DEG = 10.0
#: the geodesic centre line: at most this many samples, each joined to this many nearest
GEODESIC_SAMPLES = 8000
GEODESIC_NEIGHBOURS = 8
#: a knee bent this far (degrees, the centre lines' angle at the knee cut) hides its
#: knee waist under the thigh when none is found above the calf
HIDDEN_KNEE_FLEXION_DEG = 45.0


@dataclass(frozen=True)
class ShankRun:
    """A straight run of the centre line: ``direction`` (3,) unit, and ``half_spaces``
    ((point (3,), normal (3,)), ...) to keep, ``(p - point) . normal <= 0``; empty when
    the run does not meet a long neighbour at a bend."""

    direction: np.ndarray
    half_spaces: tuple = ()
    #: the knee's flexion at the cut, degrees (0 without one)
    flexion_deg: float = 0.0


def _binned_centroids(samples: np.ndarray, weights: np.ndarray, position: np.ndarray) -> np.ndarray:
    """(b, 3) weighted centroids of the samples (s, 3) in bins CENTRE_LINE_BIN_MM wide of
    ``position`` (s,) mm, in its order, the bins that hold a fair share of the surface."""
    bins = np.floor((position - position.min()) / CENTRE_LINE_BIN_MM).astype(np.int64)
    total = np.bincount(bins, weights=weights)
    keep = total > 0.2 * np.median(total[total > 0])
    return np.stack([np.bincount(bins, weights=weights * samples[:, i]) for i in range(3)], 1)[keep] / total[keep, None]


def _centre_line(samples: np.ndarray, weights: np.ndarray | None, axis: np.ndarray) -> np.ndarray:
    """(b, 3) centroids of the bins along ``axis`` that hold a fair share of the surface."""
    return _binned_centroids(samples, np.ones(len(samples)) if weights is None else weights, samples @ axis)


def _straight_runs(centres: np.ndarray) -> list[tuple[int, int]]:
    """Douglas-Peucker split of the centre line into straight runs (i, j), in order."""
    runs: list[tuple[int, int]] = []
    stack = [(0, len(centres) - 1)]
    while stack:
        i, j = stack.pop()
        if j - i < 2:
            runs.append((i, j))
            continue
        chord = centres[j] - centres[i]
        length = np.linalg.norm(chord)
        rel = centres[i + 1 : j] - centres[i]
        off = np.linalg.norm(rel - np.outer(rel @ chord / max(length**2, 1e-12), chord), axis=1)
        k = int(np.argmax(off))
        if off[k] <= BEND_TOLERANCE_MM:
            runs.append((i, j))
        else:
            stack += [(i, i + 1 + k), (i + 1 + k, j)]
    return sorted(runs)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.linalg.norm(v)), 1e-12)


def _knee_point(run: np.ndarray, other: np.ndarray) -> np.ndarray:
    """The knee (3,): where the shank's and the thigh's centre lines come closest (the
    bins at the bend mix both limbs, so the lines are fitted to the runs' inner bins)."""
    p, q = run.mean(axis=0), other.mean(axis=0)
    u, v = principal_axis(run), principal_axis(other)
    w = p - q
    a, b, c, d, e = u @ u, u @ v, v @ v, u @ w, v @ w
    den = a * c - b * b
    if den < 1e-9:
        return run[-1]
    s, t = (b * e - c * d) / den, (a * e - b * d) / den
    return 0.5 * ((p + s * u) + (q + t * v))


def _knee_cut(samples: np.ndarray, run: np.ndarray, other: np.ndarray) -> tuple[tuple, float]:
    """The half-space (and the knee's flexion, degrees) keeping the run of centroids ``run`` (b, 3, ordered towards the
    knee) free of the limb ``other`` (ordered away from the knee) (module docstring,
    steps 2-3)."""
    start, beyond = run[0], other[-1]
    knee = _knee_point(run, other)
    u_run, u_next = _unit(knee - start), _unit(beyond - knee)
    flexion = angle_deg(u_run, u_next)
    if flexion < MIN_FLEXION_DEG:
        return (), 0.0
    return ((knee, _unit(u_run + u_next)),), flexion


def _geodesic_centre_line(samples: np.ndarray, weights: np.ndarray | None) -> np.ndarray:
    """(b, 3) centroids of the bins of geodesic distance from one end of the leg (module
    docstring), ordered from that end.  The end is the sample furthest along the surface
    from an arbitrary one (a double sweep: a toe tip or the thigh's cut); the distance is
    Dijkstra's on the graph joining each of at most GEODESIC_SAMPLES samples (s, 3) mm
    to its GEODESIC_NEIGHBOURS nearest, over its largest connected part."""
    stride = max(len(samples) // GEODESIC_SAMPLES, 1)
    points = samples[::stride]
    w = np.ones(len(points)) if weights is None else weights[::stride]
    k = min(GEODESIC_NEIGHBOURS + 1, len(points))
    distance, nearest = cKDTree(points).query(points, k=k)
    rows = np.repeat(np.arange(len(points)), k - 1)
    graph = csr_matrix((distance[:, 1:].ravel() + 1e-9, (rows, nearest[:, 1:].ravel())), shape=(len(points),) * 2)
    _, part = connected_components(graph, directed=False)
    largest = np.flatnonzero(part == np.bincount(part).argmax())
    from_any = dijkstra(graph, directed=False, indices=int(largest[0]))
    end = int(largest[np.argmax(from_any[largest])])
    along = dijkstra(graph, directed=False, indices=end)[largest]
    return _binned_centroids(points[largest], w[largest], along)


def shank_runs(samples: np.ndarray, weights: np.ndarray | None, axis: np.ndarray) -> list[ShankRun]:
    """The straight runs of a bent leg's centre line, longest first (module docstring).

    samples (s, 3) surface samples in mm, weights (s,) or None, ``axis`` (3,) the main
    axis the centre line is binned along.  Runs shorter than :data:`MIN_RUN_MM` are left
    out.
    """
    return _runs_of(_centre_line(samples, weights, axis), samples)


def geodesic_shank_runs(samples: np.ndarray, weights: np.ndarray | None) -> list[ShankRun]:
    """:func:`shank_runs` of the geodesic centre line (module docstring): a leg bent
    so far that its main axis is the diagonal of an L.  Only runs cut free of a limb at
    a bend: a run without one is a straight leg's, which its main axis already read."""
    return [run for run in _runs_of(_geodesic_centre_line(samples, weights), samples, whole_limbs=True)
            if run.half_spaces]


def _runs_of(centres: np.ndarray, samples: np.ndarray, whole_limbs: bool = False) -> list[ShankRun]:
    """The runs of the centre line ``centres`` (b, 3), ordered along it.  With
    ``whole_limbs`` (a geodesic centre line, which runs along the limbs in order), a run
    without a long run on one side meets, as its knee's other limb, every centre past the
    short run next to it (the bend), when those span MIN_RUN_MM: a thick thigh's
    geodesic centre line bends near its source and is split into short runs."""
    runs = _straight_runs(centres)
    lengths = [float(np.linalg.norm(centres[j] - centres[i])) for i, j in runs]
    out: list[tuple[float, ShankRun]] = []
    for k, ((i, j), length) in enumerate(zip(runs, lengths)):
        if length < MIN_RUN_MM:
            continue
        # the knee: the joint with the longer of the nearest long runs on either side (a
        # thigh, not a foot; short runs in between are the bend itself)
        long_runs = [q for q, n in enumerate(lengths) if n >= MIN_RUN_MM]
        after = [q for q in long_runs if q > k]
        before = [q for q in long_runs if q < k]
        joints = []
        if after:
            a, b = runs[after[0]]
            joints.append((lengths[after[0]], centres[i : j + 1], centres[a : b + 1]))
        elif whole_limbs and k + 2 < len(runs):  # the runs past the bend (the next one) as one limb
            limb = centres[runs[k + 2][0] :]
            joints.append((float(np.linalg.norm(limb[-1] - limb[0])), centres[i : j + 1], limb))
        if before:
            a, b = runs[before[-1]]
            joints.append((lengths[before[-1]], centres[i : j + 1][::-1], centres[a : b + 1][::-1]))
        elif whole_limbs and k >= 2:
            limb = centres[: runs[k - 2][1] + 1]
            joints.append((float(np.linalg.norm(limb[-1] - limb[0])), centres[i : j + 1][::-1], limb[::-1]))
        joints = [joint for joint in joints if joint[0] >= MIN_RUN_MM]
        cut, flexion = _knee_cut(samples, *max(joints, key=lambda x: x[0])[1:]) if joints else ((), 0.0)
        out.append((length, ShankRun(_unit(centres[j] - centres[i]), cut, flexion)))
    return [run for _, run in sorted(out, key=lambda x: -x[0])]


def keep_index(points: np.ndarray, half_spaces) -> np.ndarray:
    """Indices (k,) of the points (n, 3) inside all ``half_spaces``."""
    inside = np.ones(len(points), dtype=bool)
    for point, normal in half_spaces:
        inside &= (points - np.asarray(point)) @ np.asarray(normal) <= 0.0
    return np.flatnonzero(inside)


def hidden_knee_refusal(failure: FitFailure, run: ShankRun) -> FitFailure:
    """A shank cut free of its thigh (``run``, with a knee cut) whose knee waist was not
    found above the calf: the thigh of a knee bent this far covers it
    (benchmarks/robustness.py: seated legs bent 86-97 degrees), and the refusal says so -
    ``knee_bent`` - rather than ask for a scan reaching higher, which the clinic cannot
    give while the knee is bent.  Only for a knee bent by HIDDEN_KNEE_FLEXION_DEG or more
    (a seated leg's; a standing leg's thigh leaves the shank's axis by less than 15): a
    shank cut at a slighter bend that misses its knee waist may well be a scan that stops
    short of it.  Other failures pass unchanged."""
    if failure.reason is not FailureReason.NO_KNEE or not run.half_spaces or run.flexion_deg < HIDDEN_KNEE_FLEXION_DEG:
        return failure
    return FitFailure(
        FailureReason.KNEE_BENT,
        f"the knee is bent by about {run.flexion_deg:.0f} degrees: cut free of the thigh, the shank shows its ankle "
        "and calf but not the knee waist (D) above them, which the bent knee's thigh covers (read as "
        f"{failure.reason.value}). {SCAN_STRAIGHT}")


def seated_knee_refusals(samples: np.ndarray, weights: np.ndarray | None,
                         place_run: Callable[[ShankRun], object]) -> list[FitFailure]:
    """Why a leg no main-axis reading placed is a knee bent to an L, if it is one:
    ``knee_bent`` refusals, one per run of the geodesic centre line
    (:func:`geodesic_shank_runs` of samples (s, 3) mm, weights (s,) or None) cut free of a
    limb bent HIDDEN_KNEE_FLEXION_DEG or more whose shank shows its ankle and calf -
    ``place_run(run)`` places it, or raises FitFailure for its knee waist only; none for a
    straight leg (its geodesic line bends 12 degrees at most on benchmarks/robustness.py
    220 17: an ankle_to_thigh crop) or a shank that shows less.

    Diagnosis only: a calf is never measured on a geodesic run.  It is the last resort
    after readings that measure straight and bent legs right, and there a crop of a
    straight leg was read as a shank in its thigh and fitted 110-183 mm off (seed 17
    ankle_to_thigh-04; an earlier session's geodesic readings fitted two seated legs with
    cD 14 and 24 mm off); a knee bent so far is measured straight, as RAL-GZ 387 measures."""
    out = []
    for run in geodesic_shank_runs(samples, weights):
        if run.flexion_deg < HIDDEN_KNEE_FLEXION_DEG:
            continue
        try:
            place_run(run)
        except FitFailure as failure:
            if failure.reason is FailureReason.NO_KNEE:
                out.append(hidden_knee_refusal(failure, run))
            continue
        out.append(FitFailure(
            FailureReason.KNEE_BENT,
            f"the knee is bent by about {run.flexion_deg:.0f} degrees: along the leg's own axis no calf was found, "
            "and the shank cut free of the thigh is not measured (a knee bent this far puts the thigh in the planes "
            f"across the calf and the knee waist). {SCAN_STRAIGHT}"))
    return out
