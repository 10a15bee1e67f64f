"""Which end of a leg's girth profile is the ankle's (step 2 of
:mod:`app.geometry.placement.leg_axis`): the landmarks read with the profile as it is and
upside down, the profile mirrored rather than sliced again.  A foot is at the bottom of
a leg: where one end holds a foot, that end is down.  Units: mm.  Arrays: heights (k,)
ascending, girth (k,) and elongation (k,) of the sections, NaN where unmeasured.
"""

from __future__ import annotations

import numpy as np

from app.geometry.anatomy.calf_candidates import MAX_CALF_ELONGATION, FeatureHeights
from app.geometry.anatomy.landmark_refusals import failure_stage
from app.geometry.anatomy.landmarks import find_feature_heights
from app.geometry.errors import FitFailure, FootFound
from app.geometry.sections import PolarSections


def mirror_profile(heights: np.ndarray, girth: np.ndarray, sections: PolarSections):
    """The same profile seen from the other end: z -> -z, x -> -x, y kept (a rotation
    by 180 degrees about y), so that nothing has to be sliced again."""
    n = len(sections.angles_rad)
    rays = (n // 2 - np.arange(n)) % n  # theta -> pi - theta
    mirrored = PolarSections(
        -heights[::-1],
        sections.centroids_mm[::-1] * np.array([-1.0, 1.0]),
        sections.radii_mm[::-1][:, rays],
        sections.angles_rad,
        sections.coverage[::-1],
        None if sections.largest_gap_deg is None else sections.largest_gap_deg[::-1],
        None if sections.gap_middle_rad is None else (np.pi - sections.gap_middle_rad[::-1]) % (2.0 * np.pi),
    )
    return -heights[::-1], girth[::-1], mirrored


def landmarks_either_way(heights: np.ndarray, girth: np.ndarray, elongation: np.ndarray) -> tuple[FeatureHeights, bool]:
    """Landmarks with the scan's axis as it is or reversed; (features, reversed?).

    A foot is at the bottom of a leg: where one end of the scan holds a foot (its tenth of
    the sections is elongated, MAX_CALF_ELONGATION) and the other does not, the landmarks
    are read with that end down, and read the other way they are refused (a swollen
    lower leg whose ankle is wider than its knee waist reads as a calf upside down, the
    knee waist as its ankle: benchmarks/swollen.py).  Otherwise, when both orientations
    give landmarks (possible once landmarks may lie at the scan's edge), the one with
    fewer landmarks at the edge wins, then the one whose knee end is thicker relative to
    the ankle (anatomy: D/B is 1.4-1.7, its inverse below 1).
    """
    found, failures = [], []
    for flipped in (False, True):
        h, g, e = (-heights[::-1], girth[::-1], elongation[::-1]) if flipped else (heights, girth, elongation)
        try:
            found.append((find_feature_heights(h, g, elongation=e), flipped))
        except FitFailure as failure:
            failures.append((failure, flipped))
    foot_down = foot_end(girth, elongation)  # True: the profile's bottom; False: its top; None: not told
    if foot_down is not None:
        upright = [f for f in found if f[1] != foot_down]
        if upright:
            return upright[0]
        if found:  # only upside down: the refusal of the leg read foot down
            raise next(failure for failure, flipped in failures if flipped != foot_down)
    if found:
        return min(found, key=lambda f: (f[0].b_at_scan_edge + f[0].d_at_scan_edge, -f[0].girth_d_mm / f[0].girth_b_mm))
    # report the failure of the more plausible orientation: the foot's end down; with
    # no end told by a foot, a foot found one way outranks a missing ankle the other way
    # (the foot read as a calf upside down; a missing knee found an ankle and a calf,
    # and stays); else the knee end thicker
    if foot_down is not None:
        raise failures[0][0] if foot_down else failures[1][0]
    measured = girth[np.isfinite(girth)]
    tenth = max(len(measured) // 10, 1)
    feet = [failure for failure, _ in failures if isinstance(failure, FootFound)]
    if feet and all(failure_stage(failure) <= failure_stage(feet[0]) for failure, _ in failures):
        raise feet[0]
    ends_up = bool(measured[-tenth:].mean() >= measured[:tenth].mean()) if measured.size else True
    raise failures[0][0] if ends_up else failures[1][0]


def foot_end(girth: np.ndarray, elongation: np.ndarray) -> bool | None:
    """Which end of a profile (girth (k,), elongation (k,) of its sections, NaN where
    unmeasured) holds the foot: True the bottom, False the top, None when neither or both
    of its measured tenths is elongated as a foot's sections are (median elongation over
    MAX_CALF_ELONGATION)."""
    measured = girth[np.isfinite(girth)]
    tenth = max(len(measured) // 10, 1)
    stretched = elongation[np.isfinite(elongation)]
    if stretched.size < 2 * tenth:
        return None
    foot_low = bool(np.median(stretched[:tenth]) > MAX_CALF_ELONGATION)
    foot_high = bool(np.median(stretched[-tenth:]) > MAX_CALF_ELONGATION)
    return foot_low if foot_low != foot_high else None
