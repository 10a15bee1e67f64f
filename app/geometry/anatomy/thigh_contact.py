"""Something lying against the thigh - a hand or a forearm hanging at the side, clothing
or a skin fold held or hanging over it - found where it starts, so that no tape girth is
read round the thigh and it together (RAL-GZ 387 measures the limb's skin alone; a tape
put round a hand resting on the thigh reads the hand's thickness twice).

Rule (geometry and anatomy).  Up the thigh, between the knee and the gluteal fold, the
skin's outline changes slowly: at any angle round the section it moves outwards, beyond
what the whole outline moves, by at most 6.5 mm over CONTACT_RISE_MM (20 mm) of height
(measured on 18 generated legs, benchmarks/corpus's MakeHuman legs, as 34 meshes and
noisy clouds that reach G, and the BodyParts3D leg, 5.9 mm: the quadriceps above the knee
and the buttock's edge at G give the largest).  A hand is 25-35 mm thick at the
metacarpals (adult anthropometric tables, e.g. Pheasant's Bodyspace), its fingertips
round: where it starts, an arc of the outline CONTACT_ARC_DEG wide moves out by 15-24 mm
within those 20 mm (measured: a hand 25-35 mm thick held against the side of 2 generated
thighs as a noisy cloud at 3 heights; read round it, cF came out 28-30 mm long and cG
12-35).  CONTACT_EXCESS_MM, 10 mm, lies between the two.  The thigh under the hand is not
in the scan, so the points from where the rise starts up are not measured, and say why.

A garment's hem - a shorts or trouser leg hanging loose round the thigh - moves the whole
outline out at once, which a rule read beyond the outline's median cannot see: there the
median move itself is judged against a bare thigh's (ALL_ROUND_MOVE_MM).

Frame: the calf frame (mm; z up the leg).  Arrays: heights (k,) ascending, evenly spaced.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from app.geometry.sections import TAPE_BAND_OFFSETS_MM, PolarSections

#: the outline is compared with the one this far below it, mm
CONTACT_RISE_MM = 20.0
#: ... over arcs this wide (a rise narrower is a fold of skin or a scanner's streak), degrees
CONTACT_ARC_DEG = 20.0
#: an arc moving outwards by more than this beyond the whole outline's median move over
#: CONTACT_RISE_MM of height is something lying against the thigh, mm (module docstring)
CONTACT_EXCESS_MM = 10.0
#: the thigh is searched from this far above E (the middle of the knee), mm: above the
#: patella's top (a patella is ~45 mm tall, its middle near E), where the quadriceps
#: tendon's rise is the largest a bare thigh showed (5.9 mm, the BodyParts3D leg)
CONTACT_FROM_E_MM = 50.0
#: above G the buttock bulges back and in (its arcs move out 13-32 mm over 20 mm of
#: height on 7 generated legs and the BodyParts3D leg), while within LATERAL_ARC_DEG of
#: the leg's outer side the same thighs' arcs moved at most 3.9 mm as far as they reach
#: (46-86 mm over G): a hand there still shows.  It is looked for there because a hand
#: held towards the back moves the back's profile, and G with it, down to or below its
#: fingertips (with only the arcs up to G judged, 2 of 24 hands on 8 generated legs read
#: F and G 13-25 mm low and unwarned; with 40 mm over G, 1 - a hand 24 mm over G that
#: moved it 16 mm down)
ABOVE_G_MM = 3 * CONTACT_RISE_MM
LATERAL_ARC_DEG = 60.0
#: over G, where the scan ends, two outlines whose centroids lie further apart than this
#: are not compared (mm).  The move is read to first order in the centroids' shift s,
#: which errs by about s^2 / 2r: 3.3 mm at 20 mm on a thin thigh's 60 mm radius, a third
#: of CONTACT_EXCESS_MM.  A standing thigh's axis (tilted under 15 degrees,
#: thigh.MAX_THIGH_TILT_DEG) shifts it by 20 tan 15 = 5.4 mm over CONTACT_RISE_MM, and a
#: hand's bulk on the generated legs' clouds by at most 17 mm (16.9 on 42 thighs of
#: benchmarks/hand_on_thigh.py 8 21; 6.1 at the fingertips, where those hands were found).
#: Further apart, one of the two is not the thigh's whole outline but a piece of the
#: scan's ragged top cut off by the plane (a patch 10 mm across, 90-115 mm from the
#: thigh's centroid: chart_accuracy 8 5 leg 3's clouds and hand_on_thigh 8 21 leg 2's
#: G+20 read "contacts" of 45-92 mm there)
MAX_CENTROID_SHIFT_MM = CONTACT_RISE_MM
#: the whole outline moving out by more than this over CONTACT_RISE_MM of height is a
#: garment's hem: a trouser or shorts leg hanging loose round the thigh (mm).  A bare
#: thigh's median move is its radius's rise, at most 5.1 mm over 20 mm from E + 50 mm to
#: G (179 generated scans: 76 meshes and clouds of benchmarks/hand_on_thigh.py 8 21 and
#: 12 22, the 103 of chart_accuracy.py 8 11's re-scans that read G, every degradation;
#: the three real legs 4.9); a hem adds the garment's offset from the skin to that all
#: round, which the arc rule, read beyond the median, cannot see.  7.5 mm is half as
#: much again as the bare thighs' largest.  Read round, the tape
#: reads the garment, and the back's profile turns at the hem as at a fold (a loose hem
#: 40 mm over F put G there: cF 46 and cG 32 mm short, unwarned)
ALL_ROUND_MOVE_MM = 7.5
#: a hem is looked for up to this far over G (mm): the back's profile turns at a loose
#: hem as at a fold, and G read there lay 10-11 mm under the hem (benchmarks/
#: garment_on_thigh.py), whose whole rise shows within CONTACT_RISE_MM above it.  Bare
#: thighs' median moves stayed under 5.1 mm up to 45 mm over G (the buttock's back is a
#: minority of the outline).  A hem 25-40 mm over a G read right is then said too: the
#: thigh must be bare to its fold, and a fold a hem lies that near to is not sure
HEM_OVER_G_MM = 2 * CONTACT_RISE_MM


@dataclass(frozen=True)
class ThighContact:
    """Where something starts to lie against the thigh (height, calf frame, mm) and how
    far its arc moved out beyond the outline's median move there (mm); ``all_round``:
    the whole outline moved out that far (a garment's hem), not an arc of it;
    ``inner``: the arc lies within LATERAL_ARC_DEG of the leg's inner side, where the
    other thigh presses (legs standing together: benchmarks/legs_together.py 12 41 read
    10 of 96 scans so: 8 of the 48 pressed or touching, 2 of the 24 standing 15-16 mm
    apart, at the crotch; a hand hangs at the outer side)."""

    start_mm: float
    excess_mm: float
    all_round: bool = False
    inner: bool = False

    def reason(self) -> str:
        """Why the points from :attr:`start_mm` up are not measured, for the person who scanned."""
        if self.all_round:
            return (f"the thigh is covered from {self.start_mm:.0f} mm above the ankle point B up (its whole outline "
                    f"moves out by {self.excess_mm:.0f} mm within {CONTACT_RISE_MM:.0f} mm of height, where a bare "
                    f"thigh's rises by under {ALL_ROUND_MOVE_MM:g}): the hem of a garment - a shorts or trouser leg - "
                    "hanging round the thigh; the tape would read the garment and not the skin - scan with the thigh "
                    "bare (the garment rolled up above the gluteal fold or taken off)")
        where, cause, stance = (
            ("the inner thigh", "the other thigh pressed against it, or a hand, clothing or a skin fold",
             "standing with the feet hip-width apart, the thighs not touching, and the thigh bare") if self.inner else
            ("the thigh", "a hand or forearm held against the leg, or clothing or a skin fold over it",
             "with the arms held away from the legs and the thigh bare"))
        return (f"something lies against {where} from {self.start_mm:.0f} mm above the ankle point B up (an arc of "
                f"its outline moves out by {self.excess_mm:.0f} mm within {CONTACT_RISE_MM:.0f} mm of height, where a "
                f"bare thigh's stay under {CONTACT_EXCESS_MM:.0f}): {cause}; the thigh beneath it is not in the scan, "
                f"so no tape can be read round the thigh alone there - scan {stance}")


def arc_excess(sections: PolarSections, upper: np.ndarray, lower: np.ndarray,
               arcs_judged: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How far (mm) the most-moving judged arc of each section ``upper`` (m,) int lies
    outside the section ``lower`` (m,) int below it, beyond the median move of the whole
    outline, that median move (mm), and the arc's angle (radians, the calf frame's):
    three (m,).

    Both outlines are read from the lower section's centroid, to first order in the
    centroids' shift (a few mm against a thigh's ~80 mm radius): along the ray at angle
    t the upper outline lies r_up(t) + (c_up - c_low) . u(t) out, so its move is that
    minus r_low(t); the moves are averaged over arcs CONTACT_ARC_DEG wide.  Only the arcs
    centred on the rays ``arcs_judged`` (m, a) bool count.  NaN where either section is
    missing or open over more than CONTACT_ARC_DEG, or no arc is judged.
    """
    angles = sections.angles_rad
    directions = np.column_stack([np.cos(angles), np.sin(angles)])  # (a, 2)
    shift = sections.centroids_mm[upper] - sections.centroids_mm[lower]  # (m, 2)
    move = sections.radii_mm[upper] + shift @ directions.T - sections.radii_mm[lower]  # (m, a)
    rays = max(1, int(round(CONTACT_ARC_DEG / 360.0 * len(angles))))
    arcs = uniform_filter1d(np.nan_to_num(move), rays, axis=1, mode="wrap")
    median = np.median(arcs, axis=1)
    judged_arcs = np.where(arcs_judged, arcs, -np.inf)
    most = judged_arcs.argmax(axis=1)
    excess = judged_arcs[np.arange(len(most)), most] - median
    missing = ~(sections.valid[upper] & sections.valid[lower])
    if sections.largest_gap_deg is not None:
        # a section open over more than an arc (the scan's ragged top, a hole) is bridged
        # there, not skin: its move is no contact (chart_accuracy 8 11, leg 1's clouds
        # read 12-122 mm at the hip's cut with 25-80 degrees open)
        gaps = sections.largest_gap_deg
        missing |= (gaps[upper] > CONTACT_ARC_DEG) | (gaps[lower] > CONTACT_ARC_DEG)
    median[missing] = np.nan
    excess[missing | ~arcs_judged.any(axis=1)] = np.nan
    return excess, median, angles[most]


def _holds(sections: PolarSections, rows: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Whether each outline of ``rows`` (m,) int holds the point ``offsets`` (m, 2) mm
    from its centroid: the point lies within the outline's radius along its ray."""
    angles = sections.angles_rad
    step = float(angles[1] - angles[0]) if len(angles) > 1 else 2 * np.pi
    known = np.isfinite(offsets).all(axis=1)  # a missing section has no centroid
    offsets = np.where(known[:, None], offsets, 0.0)
    ray = np.rint((np.arctan2(offsets[:, 1], offsets[:, 0]) - angles[0]) / step).astype(np.int64) % len(angles)
    return known & (np.linalg.norm(offsets, axis=1) < sections.radii_mm[rows, ray])


def thigh_contact(sections: PolarSections, rows: np.ndarray, low_mm: float, g_mm: float,
                  lateral_rad: float | None, outer_to_mm: float | None = None,
                  hem_to_mm: float | None = None) -> ThighContact | None:
    """The lowest height (mm) from ``low_mm`` up where something starts to lie against
    the thigh (module docstring): the first of ``sections``' ``rows`` (k,) int, evenly
    spaced and ascending, whose outline moves out by more than CONTACT_EXCESS_MM over an
    arc within CONTACT_RISE_MM of height, its start taken that rise lower (where it may
    have begun); None where nothing does.

    Up to G (``g_mm``) plus half a tape's width every arc is judged; above it, up to
    ``outer_to_mm`` (ABOVE_G_MM over G unless given), only the arcs within LATERAL_ARC_DEG of the leg's outer side
    (``lateral_rad``, the calf frame's angle of it; None where the side is not known:
    then none), where a hand hangs and the buttock does not bulge; there two outlines
    whose centroids lie more than MAX_CENTROID_SHIFT_MM apart are not compared.  A
    garment's hem - the whole outline moving out by more than ALL_ROUND_MOVE_MM - is
    looked for from ``low_mm`` up to ``hem_to_mm`` (HEM_OVER_G_MM over G unless given).
    """
    heights = sections.heights_mm[rows]
    if len(heights) < 2:
        return None
    lag = max(1, int(round(CONTACT_RISE_MM / float(np.median(np.diff(heights))))))
    upper = np.arange(lag, len(rows))
    top = g_mm + float(TAPE_BAND_OFFSETS_MM.max())
    anywhere = (heights[upper] >= low_mm) & (heights[upper] <= top)
    outer_to = g_mm + ABOVE_G_MM if outer_to_mm is None else outer_to_mm
    outer = (heights[upper] > top) & (heights[upper] <= outer_to) & (lateral_rad is not None)
    lateral = _off_outer_side(sections.angles_rad, lateral_rad) <= np.radians(LATERAL_ARC_DEG)
    judged = anywhere[:, None] | (outer[:, None] & lateral[None, :])  # (m, a)
    hem_to = g_mm + HEM_OVER_G_MM if hem_to_mm is None else hem_to_mm
    hem_reach = (heights[upper] >= low_mm) & (heights[upper] <= hem_to)
    searched = anywhere | outer | hem_reach
    upper_rows, lower_rows = rows[upper[searched]], rows[upper[searched] - lag]
    excess, median, arc_angle = arc_excess(sections, upper_rows, lower_rows, judged[searched])
    # over G the scan ends: an outline far from the one below it is a piece of the
    # scan's ragged top, not compared.  Below G the thigh runs on through every plane
    # (its fold lies above), so such an outline is the plane's cut through something
    # beside the thigh (a hand apart from a sparse cloud's thigh): judged, it moves out
    # by far more than CONTACT_EXCESS_MM
    shift = sections.centroids_mm[lower_rows] - sections.centroids_mm[upper_rows]  # (m, 2)
    over_g = heights[upper[searched]] > top
    excess[over_g & (np.linalg.norm(shift, axis=1) > MAX_CENTROID_SHIFT_MM)] = np.nan
    # ... and its median move not where the upper outline does not even hold the lower's
    # centroid (a loose garment's tube, hanging from the buttock, may lie 20-30 mm off the
    # thigh's axis and still hold it; the top's sliver does not)
    median[over_g & ~_holds(sections, upper_rows, shift)] = np.nan
    hem = hem_reach[searched] & (median > ALL_ROUND_MOVE_MM)
    over = np.flatnonzero((excess > CONTACT_EXCESS_MM) | hem)
    if not len(over):
        return None
    start = float(heights[upper[searched][over[0]]] - CONTACT_RISE_MM)
    if excess[over[0]] > CONTACT_EXCESS_MM:
        inner = lateral_rad is not None and bool(
            _off_outer_side(arc_angle[over[0]], lateral_rad) >= np.pi - np.radians(LATERAL_ARC_DEG))
        return ThighContact(start, float(excess[over[0]]), inner=inner)
    return ThighContact(start, float(median[over[0]]), all_round=True)


def _off_outer_side(angles_rad: np.ndarray, lateral_rad: float | None) -> np.ndarray:
    """How far (radians, 0..pi) each angle lies round the section from the leg's outer
    side ``lateral_rad`` (0 where it is not known: the angles as they are)."""
    return np.abs((angles_rad - (lateral_rad or 0.0) + np.pi) % (2 * np.pi) - np.pi)
