"""Is the leg scanned all round?  A tape girth is the whole circumference; a scan that
sees the leg from one side (a depth camera's single view, a hand-held pass that never
went behind the leg) or misses a strip along it holds only an arc of each section, and
every girth measured from it is a guess.

The coarse profile's sections along the candidate leg (app.geometry.placement.leg_axis)
each know their largest arc without skin and where it points
(:attr:`app.geometry.sections.PolarSections.largest_gap_deg`, ``gap_middle_rad``).  The
leg is refused as ``partial_view``, before any landmark is looked for (a missing arc
reads as a leg of another shape, and the refusal would name an ankle, calf or knee that
the scan does hold), when

- at least :data:`ONE_SIDED_SHARE` of its sections holding skin miss more than
  MAX_GAP_DEG of it, and
- those arcs point the same way: the mean resultant length of their directions is at
  least :data:`SAME_DIRECTION` (Rayleigh's test of uniformity on the circle; Mardia &
  Jupp, Directional Statistics, 6.3.1) - a strip the scanner never saw, not a sparse
  cloud's gaps scattered round the leg (those are refused as too sparse) - or at least
  :data:`MOST_SHARE` of the sections are open so, wherever their arcs point (a half
  leg's sections are arcs whose centres, and so the directions of their gaps, wander;
  a cloud that sparse is refused as too sparse by app.geometry.placement.place).

Units: degrees, shares.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from app.geometry.anatomy.level_points import GIRTH_TOLERANCE_MM
from app.geometry.errors import BridgedStrip, FailureReason, FitFailure, JoinedAboveCalf
from app.geometry.sections.polar import MAX_GAP_DEG, PolarSections

#: a strip missing along a quarter of the leg's length: a hole spans a few cm of it (the
#: corpus's holes, cropped ends and legs cut apart at the crotch open at most 13% of a
#: leg's sections by more than MAX_GAP_DEG: benchmarks/robustness.py 220 7 and 220 11)
ONE_SIDED_SHARE = 0.25
#: mean resultant length of the open arcs' directions: n directions drawn uniformly give
#: about 1 / sqrt(n) (0.1 for 100 sections; Rayleigh's P(R >= 0.5) ~ exp(-n / 4) for 25 or
#: more), a strip along the leg close to 1
SAME_DIRECTION = 0.5
#: ... or this share, whichever way the arcs point
MOST_SHARE = 0.75
#: a landmark's girth is read across a tape's width (app.geometry.sections
#: TAPE_BAND_OFFSETS_MM, +-4 mm): the calf's sections this close to it count, mm
BRIDGE_READ_MM = 4.0


def _share_and_side(sections: PolarSections, gapped: np.ndarray) -> tuple[float, bool]:
    """The share of the sections holding skin that are ``gapped`` (k,) bool, and whether
    their gaps point the same way (Rayleigh's mean resultant length of the gaps'
    directions at least SAME_DIRECTION; module docstring).  Needs ``gap_middle_rad``."""
    held = sections.coverage > 0
    share = float(gapped[held].mean()) if held.any() else 0.0
    assert sections.gap_middle_rad is not None
    same_side = bool(gapped.any()) and float(np.abs(np.exp(1j * sections.gap_middle_rad[gapped]).mean())) >= SAME_DIRECTION
    return share, same_side


def partial_view(sections: PolarSections) -> FitFailure | None:
    """The refusal of a leg seen from one side (module docstring), or None."""
    if sections.gap_middle_rad is None:
        return None
    open_arc = sections.open_arcs()
    share, same_side = _share_and_side(sections, open_arc)
    if share < ONE_SIDED_SHARE:
        return None
    if not same_side and share < MOST_SHARE:
        return None
    assert sections.largest_gap_deg is not None  # open_arcs is all False without it
    arcs = sections.largest_gap_deg[open_arc]
    return FitFailure(
        FailureReason.PARTIAL_VIEW,
        f"the scan does not go all round the leg: at {share:.0%} of its heights an arc of {np.median(arcs):.0f} "
        f"degrees (up to {arcs.max():.0f}) {'on the same side of' if same_side else 'around'} the leg holds no skin - "
        "it was scanned from one side, or a strip along the leg is missing. A tape girth is the whole circumference (a "
        f"hole is bridged up to {MAX_GAP_DEG:.0f} degrees): scan all round the leg, or merge the scanner's views "
        "before exporting.")


#: the refusals about the leg's shape that a strip bridged in every section can cause
SHAPE_REFUSALS = (FailureReason.NO_ANKLE, FailureReason.NO_KNEE, FailureReason.NO_CALF, FailureReason.NOT_A_LEG)


def bridged_strip_refusal(failure: FitFailure, sections: PolarSections) -> FitFailure | None:
    """A refusal about the leg's shape (``failure``: no ankle, knee waist or calf found on
    the profile of ``sections``) re-read as ``partial_view`` when the profile was read
    through a strip the scanner missed, or None.

    :func:`partial_view` refuses a strip whose arcs exceed MAX_GAP_DEG; narrower ones are
    bridged by the slicer's chord and read.  A bridge under-reads a section's girth by up
    to :func:`arc_bridge_bound_mm`: 3 mm (an order's tolerance, GIRTH_TOLERANCE_MM) at a
    45-degree arc on a 60 mm calf radius, 35 mm at 90 degrees, against a knee waist that
    dips 5-15% (20-60 mm) below the calf and the knee.  So when the landmarks are not
    found and at least ONE_SIDED_SHARE of the sections holding skin miss an arc whose
    bridge may move their girth by more than that tolerance - the test the fit warns on
    (:func:`bridged_arcs`) - on the same side of the leg (Rayleigh's mean resultant length
    at least SAME_DIRECTION, as :func:`partial_view`), the missing strip is the likelier
    cause, and asking for the knee or the ankle the scan holds would send the clinic the
    wrong way.  Measured on benchmarks/coverage.py 20 31, leg 10: a cloud missing a strip
    of 107 degrees read its arcs as 85-110 degrees (median 100, the limit: seen from the
    remaining skin's centroid, which the missing strip shifts away from it, an arc looks
    narrower) at 20-24% of its heights beyond the limit and was refused ``no_knee``.
    The refusal keeps the shape reading's words."""
    # (a join of another body part above the leg is read off the girth's jump, which no
    # missing strip makes: that refusal names the cause)
    if (failure.reason not in SHAPE_REFUSALS or isinstance(failure, JoinedAboveCalf)
            or sections.largest_gap_deg is None or sections.gap_middle_rad is None):
        return None
    held = sections.coverage > 0
    radius = sections.mean_radii()  # NaN where the section was not read (a cloud's open beyond the limit)
    missed = chord_arcs_deg(sections)
    bound = arc_bridge_bound_mm(np.nan_to_num(radius), np.minimum(missed, MAX_GAP_DEG))
    bridged = np.isfinite(sections.gap_middle_rad) & (sections.open_arcs() | (held & (bound > GIRTH_TOLERANCE_MM)))
    share, same_side = _share_and_side(sections, bridged)
    if share < ONE_SIDED_SHARE or not same_side:
        return None
    arcs = missed[bridged]
    return BridgedStrip(
        f"the leg's shape could not be read ({failure.reason.value}: {failure.detail.split('. ')[0]}), and at "
        f"{share:.0%} of its heights an arc of {np.median(arcs):.0f} degrees (up to {arcs.max():.0f}) on the same "
        "side of the leg holds no skin - a strip the scanner missed, or a view from one side. Bridged across such an "
        f"arc a girth may be off by {np.median(bound[bridged]):.0f} mm or more, enough to hide an ankle or a knee "
        "waist: scan all round the leg, or merge the scanner's views before exporting.")


def without_open_arcs(sections: PolarSections) -> PolarSections:
    """A mesh's ``sections`` with those open by more than MAX_GAP_DEG made missing, as a
    cloud's are (app.geometry.sections.cloud): the mesh slicer bridges any gap its rays
    leave while half of them hit, and a bridge over more than MAX_GAP_DEG is a guess at
    the leg's shape, not a measurement of it (a 100-degree chord under-reads a 60 mm
    radius arc by 13 mm of girth)."""
    if sections.largest_gap_deg is None:
        return sections
    open_arc = sections.largest_gap_deg > MAX_GAP_DEG
    if not open_arc.any():
        return sections
    return dataclasses.replace(sections, radii_mm=np.where(open_arc[:, None], np.nan, sections.radii_mm),
                               centroids_mm=np.where(open_arc[:, None], np.nan, sections.centroids_mm))


def open_arcs_failure(sections: PolarSections, what: str, cut_at_knee: bool = False) -> FitFailure | None:
    """The refusal of ``what`` (e.g. "the calf's cross-sections") when most of its missing
    sections hold skin but are open by more than MAX_GAP_DEG - a strip the scanner missed,
    or a view from one side - or None (then they are missing for another reason).  None
    too on a shank ``cut_at_knee`` (free of a bent knee's thigh): the cut opens sections
    near it, and a refusal asking to scan all round would send the clinic the wrong way
    (the corpus's seated legs: benchmarks/robustness.py 220 11, seated-02)."""
    if sections.largest_gap_deg is None or cut_at_knee:
        return None
    missing = ~sections.valid
    open_arc = missing & sections.open_arcs()
    if not missing.any() or open_arc.sum() * 2 < missing.sum():
        return None
    arcs = sections.largest_gap_deg[open_arc]
    return FitFailure(
        FailureReason.PARTIAL_VIEW,
        f"{what} are not whole: at {open_arc.mean():.0%} of them an arc of {np.median(arcs):.0f} degrees (up to "
        f"{arcs.max():.0f}) around the leg holds no skin - a strip the scanner missed, a large hole, a view from "
        "one side, or the back of the calf hidden by a knee bent onto it. A tape girth is the whole circumference (a "
        f"hole is bridged up to {MAX_GAP_DEG:.0f} degrees): scan all round the leg, standing or with the knee "
        "straight, or merge the scanner's views before exporting.")


def arc_bridge_bound_mm(radius_mm: np.ndarray, arc_deg: np.ndarray) -> np.ndarray:
    """How far a girth bridged across a missing arc may be off, mm: a convex section's
    skin over an arc it misses lies between the chord of the arc and the tangents at its
    ends, whose lengths differ by 2 r (tan(a/2) - sin(a/2)) on a section of mean radius
    r (mm) missing a degrees (1.1 mm for 30 degrees at r = 60 mm, 3.8 for 45, 35 for 90).
    Shapes broadcast."""
    half = np.radians(np.asarray(arc_deg, dtype=float)) / 2.0
    return 2.0 * np.asarray(radius_mm, dtype=float) * (np.tan(half) - np.sin(half))


def chord_arcs_deg(sections: PolarSections) -> np.ndarray:
    """(k,) the arc each section misses, degrees, read from the chord across its largest
    gap: the arc a chord that long cuts from a circle of the section's mean radius,
    2 arcsin(c / 2 r) - or the gap as seen from the section's centre where that is wider;
    0 without a gap.  Seen from the centre of the skin that remains - which the missing
    arc shifts away from it - the gap looks narrower than it is: a strip of 53 degrees
    along a generated leg looked 40 (median over its sections; benchmarks/coverage.py 20
    37, leg 17) and a 107-degree one 85-110 (20 31, leg 10); its chord's length does not
    depend on where it is seen from.  Needs ``largest_gap_deg`` and ``gap_middle_rad``."""
    assert sections.largest_gap_deg is not None and sections.gap_middle_rad is not None
    seen = np.where(np.isfinite(sections.largest_gap_deg), sections.largest_gap_deg, 0.0)
    rows = np.flatnonzero((seen > 0) & (seen < 360) & np.isfinite(sections.gap_middle_rad) & sections.valid)
    if not rows.size:
        return seen
    radii, n_rays = sections.radii_mm[rows], len(sections.angles_rad)
    ends = sections.gap_middle_rad[rows, None] + np.radians(seen[rows, None]) * np.array([-0.5, 0.5])  # (m, 2)
    # the skin at the gap's two ends: the radii read periodically between the rays
    ray = np.mod(ends / (2 * np.pi) * n_rays, n_rays)
    low = np.floor(ray).astype(np.int64) % n_rays
    share = ray - np.floor(ray)
    reach = (1 - share) * np.take_along_axis(radii, low, 1) + share * np.take_along_axis(radii, (low + 1) % n_rays, 1)
    skin = reach[..., None] * np.stack([np.cos(ends), np.sin(ends)], axis=-1)  # (m, 2, 2)
    chord = np.linalg.norm(skin[:, 0] - skin[:, 1], axis=1)
    arc = np.degrees(2 * np.arcsin(np.clip(chord / (2 * radii.mean(axis=1)), 0.0, 1.0)))
    out = seen.copy()
    out[rows] = np.maximum(seen[rows], arc)
    return out


def bridged_arcs(sections: PolarSections, landmark_heights_mm: dict[str, float]) -> dict[str, tuple[float, float]]:
    """name -> (the arc missed, degrees; how far the girth may be off, mm) of each
    landmark whose skin (its section and those within BRIDGE_READ_MM of it, the tape's
    band) misses an arc whose bridge may move the girth by more than an order's tolerance
    (:func:`arc_bridge_bound_mm` over GIRTH_TOLERANCE_MM).  ``sections``: the calf's,
    heights (k,) mm; none without gaps measured."""
    if sections.largest_gap_deg is None:
        return {}
    radius = sections.mean_radii()
    bound = np.where(np.isfinite(radius), arc_bridge_bound_mm(np.nan_to_num(radius), sections.largest_gap_deg), 0.0)
    out = {}
    for name, height in landmark_heights_mm.items():
        near = np.abs(sections.heights_mm - height) <= BRIDGE_READ_MM
        if near.any() and bound[near].max() > GIRTH_TOLERANCE_MM:
            out[name] = (float(sections.largest_gap_deg[near].max()), float(bound[near].max()))
    return out


def bridged_arc_warning(arcs: dict[str, tuple[float, float]]) -> str | None:
    """The fit's warning for :func:`bridged_arcs`' landmarks, or None."""
    if not arcs:
        return None
    return (f"the skin at {', '.join(arcs)} misses an arc of up to {max(a for a, _ in arcs.values()):.0f} degrees "
            "around the leg (a hole, or a strip the scanner missed): the girth there is bridged across it and may be "
            f"off by up to {max(b for _, b in arcs.values()):.0f} mm (a convex section's skin lies between the arc's "
            "chord and its tangents); take it by tape, or scan that side again")
