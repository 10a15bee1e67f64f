"""Ground truth of a generated leg: tape girths and heights of B, B1, C, D.

Measured on the clean mesh, independently of the fitting core (trimesh's plane
sections and scipy's convex hull, not ``app.geometry``): planes perpendicular to the
shank axis every 1 mm, the axis first from the ankle joint to the knee joint, then
refined as the line through the section centroids between them (a tape is held
perpendicular to the leg's long axis).  On the hull (tape) girth profile, lightly
smoothed (Gaussian, sigma 3 mm): C is the largest girth from 20% of the shank up to
the knee waist (the smallest girth above the largest in the middle 20-80% of the shank,
up to 60 mm above the knee joint), B the smallest between the ankle joint and C, D the smallest between C and
60 mm above the knee joint, B1 the first height above B where the girth has risen half
of the way from B's to C's (the steepest point of a sigmoid rise, paper section 2.2;
until 2026-12 it was the largest slope itself, which moves with the noise of a
flat-topped derivative: app.geometry.anatomy.feature_layers.b1_height says why).
On a flat calf, C is then moved to the middle of its crown: the heights around the
maximum whose girth a tape cannot tell from it (within 0.5%, the same definition as
the service's, since the paper's "maximum" is not a height on a plateau).
A bent knee brings the thigh into the upper planes: the shank's sections end where
the girth jumps (:data:`MERGE_RISE`), and C and D are looked for below that.
Girths are read on the unsmoothed profile at those heights.  Units: mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.ndimage import gaussian_filter1d
from scipy.spatial import ConvexHull, QhullError

STEP_MM = 1.0
SMOOTH_MM = 3.0
KNEE_REACH_MM = 60.0
#: a leg's girth rises at most ~1%/mm anywhere above the ankle (knee: ~0.5%/mm); a
#: rise of 10% within 5 mm means the plane has reached another body part (the thigh)
MERGE_RISE = 0.10
MERGE_RUN_MM = 5.0
#: the calf's crown: girths within this fraction of the maximum (tape resolution)
CROWN_FRACTION = 0.005
#: the least change of girth a tape tells: it reads to 1 mm, +-1 mm at each end
TAPE_RESOLUTION_MM = 2.0


@dataclass(frozen=True)
class LegTruth:
    """Truth of one leg, in the generating (MakeHuman, mm) coordinates.

    heights_mm : name -> height along the shank axis above B (B is 0).
    girths_mm : name -> tape girth (convex-hull perimeter) of the section, mm.
    points_mm : name -> (3,) the section centroid at that landmark.
    axis : (3,) unit shank axis, ankle -> knee.
    knee_hidden : a bent knee's thigh reaches into the planes before the girth has
        its minimum above the calf: the knee waist cannot be measured on this leg.
    knee_rise_mm : how far above D the (smoothed) girth has risen by a tape's
        resolution (TAPE_RESOLUTION_MM): a scan that stops below that shows no knee
        waist a tape could tell from a leg still narrowing (NaN: no such rise measured).
    """

    heights_mm: dict
    girths_mm: dict
    points_mm: dict
    axis: np.ndarray
    knee_hidden: bool = False
    knee_rise_mm: float = float("nan")

    def as_dict(self) -> dict:
        return {"heights_mm": self.heights_mm, "girths_mm": self.girths_mm,
                "points_mm": {k: v.tolist() for k, v in self.points_mm.items()}, "axis": self.axis.tolist()}


def _hull_profile(mesh: trimesh.Trimesh, origin: np.ndarray, axis: np.ndarray, heights: np.ndarray):
    """Tape girth (k,) and 3D centroid (k, 3) of the plane sections at ``heights``."""
    lines, transforms, _ = trimesh.intersections.mesh_multiplane(mesh, origin, axis, heights)
    girth = np.full(len(heights), np.nan)
    centre = np.full((len(heights), 3), np.nan)
    for k, (segments, to_world) in enumerate(zip(lines, transforms)):
        if len(segments) < 3:
            continue
        pts = segments.reshape(-1, 2)
        try:
            hull = ConvexHull(pts)
        except QhullError:
            continue
        ring = pts[hull.vertices]
        girth[k] = np.linalg.norm(np.roll(ring, -1, axis=0) - ring, axis=1).sum()
        length = np.linalg.norm(segments[:, 1] - segments[:, 0], axis=1)
        mid = segments.mean(axis=1)
        c2 = (mid * length[:, None]).sum(axis=0) / max(length.sum(), 1e-12)
        centre[k] = trimesh.transform_points(np.array([[c2[0], c2[1], 0.0]]), to_world)[0]
    return girth, centre


def measure_truth(mesh: trimesh.Trimesh, ankle_mm: np.ndarray, knee_mm: np.ndarray) -> LegTruth:
    """Truth landmarks of the single clean leg ``mesh`` (mm); see the module docstring."""
    axis = (knee_mm - ankle_mm) / np.linalg.norm(knee_mm - ankle_mm)
    shank = float(np.linalg.norm(knee_mm - ankle_mm))
    heights = np.arange(0.0, shank + KNEE_REACH_MM + STEP_MM / 2, STEP_MM)
    origin = ankle_mm
    for _ in range(2):
        girth, centre = _hull_profile(mesh, origin, axis, heights)
        inner = (heights > 0.1 * shank) & (heights < 0.9 * shank) & np.isfinite(girth)
        pts = centre[inner]
        mean = pts.mean(axis=0)
        direction = np.linalg.svd(pts - mean)[2][0]
        direction = direction if direction @ axis > 0 else -direction
        # keep the ankle end: the new origin is where the old one projects on the new line
        origin = mean + ((origin - mean) @ direction) * direction
        axis = direction
    girth, centre = _hull_profile(mesh, origin, axis, heights)
    ok = np.isfinite(girth)
    g = gaussian_filter1d(np.interp(heights, heights[ok], girth[ok]), SMOOTH_MM / STEP_MM, mode="nearest")
    # a bent knee: near the knee the planes reach the thigh, and the section's girth
    # jumps; the shank's own sections end where the girth first rises by more than
    # MERGE_RISE within MERGE_RUN_MM in the upper half of the shank
    run = int(MERGE_RUN_MM / STEP_MM)
    rise = np.zeros(len(g), dtype=bool)
    rise[:-run] = (g[run:] > (1.0 + MERGE_RISE) * g[:-run]) & (heights[:-run] > 0.5 * shank)
    end = heights[np.argmax(rise)] if rise.any() else shank + KNEE_REACH_MM
    # C is the largest girth below the knee waist: sought first in the middle 20-80% of the
    # shank, then, with the knee waist above that (the smallest girth from there up to the
    # merge or 60 mm over the knee joint), up to the waist.  Until 2026-12 it was sought
    # in the 20-80% only, which put a flat calf's C at that cap, 40 mm under its crown
    # (benchmarks/robustness.py 220 31 floor-07)
    mid = (heights >= 0.2 * shank) & (heights <= min(0.8 * shank, end))
    first = np.flatnonzero(mid)[np.argmax(g[mid])]
    knee = (heights > heights[first]) & (heights <= min(shank + KNEE_REACH_MM, end))
    if knee.any():
        mid = (heights >= 0.2 * shank) & (heights < heights[np.flatnonzero(knee)[np.argmin(g[knee])]])
    ic = np.flatnonzero(mid)[np.argmax(g[mid])]
    below = np.flatnonzero(heights < heights[ic])
    ib = below[np.argmin(g[below])]
    above = np.flatnonzero((heights > heights[ic]) & (heights <= min(shank + KNEE_REACH_MM, end)))
    id_ = above[np.argmin(g[above])] if above.size else ic
    # the knee waist is hidden when the girth is still falling where the thigh merges
    # (still falling: more than 2% over the last 10 mm, twice the girth noise)
    edge = int(np.searchsorted(heights, end))
    falling = edge >= 10 and g[edge - 10] > 1.02 * g[edge - 1]
    # ... or when the thigh merges before the girth has fallen off the calf's crown by
    # those 2% at all: the "knee waist" is then the merge's edge, a few mm above C and as
    # round as it (robustness 220 11 seated-02: D 5 mm above C, 354.3 mm against 354.2)
    never_fell = bool(rise.any()) and g[id_] >= 0.98 * g[ic]
    at_merge = end - heights[id_] <= MERGE_RUN_MM
    knee_hidden = bool(at_merge and (falling or never_fell)) or bool(end - heights[ic] <= MERGE_RUN_MM)
    crown = np.flatnonzero(np.abs(g - g[ic]) <= CROWN_FRACTION * g[ic])
    crown = crown[(crown > ib) & (crown < id_)]
    if crown.size:  # the run of crown heights that holds the maximum, and its middle
        runs = np.split(crown, np.flatnonzero(np.diff(crown) > 1) + 1)
        run = next((r for r in runs if r[0] <= ic <= r[-1]), np.array([ic]))
        ic = int(run[np.argmin(np.abs(heights[run] - 0.5 * (heights[run[0]] + heights[run[-1]])))])
    # B and D: the vertex of the least-squares parabola over the unsmoothed girth within
    # WAIST_FIT_MM of the lowest section (the service's rule since 2026-12: a flat
    # waist's lowest single section moves with the noise), when the window is measured
    b_mm, d_mm = _waist(heights, girth, ib), _waist(heights, girth, id_)
    between = np.arange(ib + 1, ic)
    risen = between[g[between] >= 0.5 * (g[ib] + g[ic])]
    ib1 = int(risen[0]) if risen.size else (ib + ic) // 2
    index = {"B": ib, "B1": ib1, "C": ic, "D": id_}
    at = {k: float(heights[i]) for k, i in index.items()} | {"B": b_mm, "D": d_mm}
    if (b_mm, d_mm) != (heights[ib], heights[id_]):  # the waists' own sections, measured where they are
        girth_bd, centre_bd = _hull_profile(mesh, origin, axis, np.array([b_mm, d_mm]))
    else:
        girth_bd, centre_bd = girth[[ib, id_]], centre[[ib, id_]]
    girths = {k: float(girth[i]) for k, i in index.items()} | {"B": float(girth_bd[0]), "D": float(girth_bd[1])}
    points = {k: centre[i] for k, i in index.items()} | {"B": centre_bd[0], "D": centre_bd[1]}
    risen_d = np.flatnonzero((heights > d_mm) & (g >= girths["D"] + TAPE_RESOLUTION_MM))
    return LegTruth(
        heights_mm={k: at[k] - b_mm for k in index},
        girths_mm=girths,
        points_mm=points,
        axis=axis,
        knee_hidden=knee_hidden,
        knee_rise_mm=float(heights[risen_d[0]] - d_mm) if risen_d.size else float("nan"),
    )


#: half-width of the waist parabola, mm (app.geometry.anatomy.waists.WAIST_FIT_MM says why)
WAIST_FIT_MM = 20.0


def _waist(heights: np.ndarray, girth: np.ndarray, index: int) -> float:
    """Vertex height of the parabola fitted to ``girth`` within WAIST_FIT_MM of ``index``."""
    z0 = float(heights[index])
    near = (np.abs(heights - z0) <= WAIST_FIT_MM) & np.isfinite(girth)
    if z0 - WAIST_FIT_MM < heights[0] or z0 + WAIST_FIT_MM > heights[-1] or near.sum() < 10:
        return z0
    c, b, _ = np.polyfit(heights[near] - z0, girth[near], 2)
    offset = -b / (2.0 * c) if c > 0 else np.inf
    return z0 + float(offset) if abs(offset) <= WAIST_FIT_MM / 2 else z0


def quick_girths(vertices_dm: np.ndarray) -> tuple[float, float]:
    """Tape girths at B and C (mm) of the left leg of an unsubdivided blend (for sizing)."""
    from benchmarks.corpus.makehuman import DM, joints_mm, makehuman

    z = makehuman()
    skin = vertices_dm[: int(z["n_skin"])] * DM
    faces = z["faces"].astype(np.int64)
    keep = skin[:, 0] > 0
    mesh = trimesh.Trimesh(skin, faces[keep[faces].all(axis=1)], process=False)
    joints = joints_mm(vertices_dm)
    ankle, knee = joints["l-ankle"], joints["l-knee"]
    axis = (knee - ankle) / np.linalg.norm(knee - ankle)
    shank = float(np.linalg.norm(knee - ankle))
    heights = np.arange(0.0, shank, 3.0)
    girth, _ = _hull_profile(mesh, ankle, axis, heights)
    ok = np.isfinite(girth)
    mid = ok & (heights > 0.2 * shank) & (heights < 0.8 * shank)
    ic = np.flatnonzero(mid)[np.argmax(girth[mid])]
    low = ok & (heights < heights[ic])
    return float(girth[low].min()), float(girth[ic])
