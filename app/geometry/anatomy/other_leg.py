"""The other leg beside the measured one: on which side of it the scan holds a second leg.

A scan of two legs of which only one could be placed (the other cut short above its
ankle, or not whole) is measured on the one leg found.  Where the second leg stands
tells that leg's side without the foot: a person's legs stand side by side, the left
one on the subject's left (-x in the calf frame, whose x is the subject's right:
anterior x up, as :mod:`app.geometry.anatomy.side` and the two-leg split use).  A side
given against that position is the other leg's, which this scan cannot measure.

The rule, in horizontal slabs of the calf frame (mm, z up the leg from B, 20 mm thick,
every 20 mm from B to :data:`REACH_ABOVE_D_MM` above the knee waist D):

1. the slab's points on a coarse occupancy grid (:func:`slab_blobs`: closed, holes
   filled, so a mesh's ring and a cloud's scatter both give the section's area);
2. the measured leg's own blob is the one whose centre is nearest its calf axis
   (x = y = 0; above D the thigh drifts from that axis by a few cm, the other thigh's
   centre lies two thigh radii away);
3. a second leg beside it is a blob at least :data:`LEG_AREA_SHARE` of the own blob's
   area (a calf, knee or thigh beside a calf, knee or thigh; a hand or a forearm, the
   only other limbs that reach below mid-thigh, are a fifth of a thigh's section or less)
   whose centre lies at least :data:`MIN_APART_MM` from the own blob's (two shins'
   centres are at least that far apart: :mod:`app.geometry.placement.calf_frame`);
4. the side is told when at least :data:`MIN_SLABS` slabs hold such a blob (60 mm of a
   leg, not a fragment) and at least :data:`MIN_AGREEMENT` of them hold it on one side
   only (a slab with leg-sized blobs on both sides votes for neither).

Slabs where the two legs touch (knees, the crotch) read one merged blob and count for
nothing; so do slabs with a second leg seen only as an open arc (a partial view of it),
whose filled area is a strip.  Both leave the side to the foot, as before.

Fewer slabs than :data:`MIN_SLABS` do not tell a side alone (40 mm of a leg-sized blob
may be a scrap), but they can confirm another cue.  A leg cut off 600-650 mm above its
sole leaves only its upper thigh, at the top of the band or above it, often merged with
the measured one at the crotch: :func:`other_leg_confirmed` reads the scan to its top,
counts the merged sections too and asks :data:`CONFIRMING_SLABS` slabs.  Such a leg, on
the side a confident foot says, is evidence enough to refuse a side given against both
(:func:`app.geometry.placement.place.place_leg`), never to tell a side alone.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

SLAB_MM = 20.0
#: slabs reach this far above the knee waist D: knee and lower thigh, below the finger
#: tips of a standing person (ANSUR II: fingertip height ~0.38 of stature, D ~0.28)
REACH_ABOVE_D_MM = 250.0
#: a second leg's section is at least this share of the measured leg's at the same height
LEG_AREA_SHARE = 0.5
#: the least distance between two legs' section centres, mm
MIN_APART_MM = 60.0
MIN_SLABS = 3
#: slabs that confirm a side another cue told (a ragged cut edge fills one slab at most)
CONFIRMING_SLABS = 2
MIN_AGREEMENT = 0.9


@dataclass(frozen=True)
class OtherLeg:
    """A second leg beside the measured one: ``side`` "left" / "right" of the measured
    leg it stands on, the number of ``slabs`` it was seen in and the median over those
    slabs of the nearest such blob's centre ``offset_mm`` from the measured leg's
    (horizontal, mm)."""

    side: str
    slabs: int
    offset_mm: float

    @property
    def measured_side(self) -> str:
        """The measured leg's side: the one away from the other leg."""
        return "right" if self.side == "left" else "left"


def slab_blobs(points_xy: np.ndarray, pixel_mm: float) -> tuple[np.ndarray, np.ndarray]:
    """Filled areas (k,) in mm^2 and centres (k, 2) in mm of the separate blobs of
    (n, 2) points on an occupancy grid of ``pixel_mm`` cells (closed once, holes filled)."""
    if len(points_xy) < 10:
        return np.zeros(0), np.zeros((0, 2))
    origin = points_xy.min(axis=0)
    cells = np.floor((points_xy - origin) / pixel_mm).astype(np.int64) + 1
    grid = np.zeros(cells.max(axis=0) + 2, dtype=bool)
    grid[cells[:, 0], cells[:, 1]] = True
    grid = ndimage.binary_fill_holes(ndimage.binary_closing(grid, iterations=1))
    labels, count = ndimage.label(grid)
    if count == 0:
        return np.zeros(0), np.zeros((0, 2))
    index = np.arange(1, count + 1)
    areas = ndimage.sum_labels(grid, labels, index) * pixel_mm**2
    centres = np.array(ndimage.center_of_mass(grid, labels, index)).reshape(-1, 2)
    return areas, origin + (centres - 1.0 + 0.5) * pixel_mm


def _slabs(calf_points: np.ndarray, top_mm: float, pixel_mm: float) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The blobs (areas (k,) mm^2, centres (k, 2) mm) of each 20 mm slab from B up to
    ``top_mm``, bottom first; only the band's points are sorted, not the scan."""
    n_slabs = len(np.arange(SLAB_MM / 2, top_mm, SLAB_MM))  # ~30
    slab = np.floor(calf_points[:, 2] / SLAB_MM).astype(np.int64)
    inside = np.flatnonzero((slab >= 0) & (slab < n_slabs))
    inside = inside[np.argsort(slab[inside], kind="stable")]
    bounds = np.searchsorted(slab[inside], np.arange(n_slabs + 1))
    for lo, hi in zip(bounds[:-1], bounds[1:]):  # one slab at a time
        yield slab_blobs(calf_points[inside[lo:hi], :2], pixel_mm)


def _beside_vote(areas: np.ndarray, centres: np.ndarray) -> tuple[float, float] | None:
    """A slab's vote (-1 left, +1 right, 0 both) and the nearest leg-sized blob's distance
    (mm) from the measured leg's, or None when no leg-sized blob stands beside it (rules
    2-3 of the module docstring)."""
    if len(areas) < 2:
        return None
    own = int(np.argmin(np.linalg.norm(centres, axis=1)))
    apart = centres - centres[own]
    beside = (areas >= LEG_AREA_SHARE * areas[own]) & (np.linalg.norm(apart, axis=1) >= MIN_APART_MM)
    if not beside.any():
        return None
    # a slab votes for a side when every leg-sized blob beside it lies on that side
    across = np.sign(apart[beside, 0])
    return (float(across[0]) if (across == across[0]).all() else 0.0), float(np.linalg.norm(apart[beside], axis=1).min())


def _told(votes: list[float], offsets: list[float], min_slabs: int) -> OtherLeg | None:
    """Rule 4: the side at least ``min_slabs`` votes agree on (MIN_AGREEMENT of them)."""
    if len(votes) < min_slabs:
        return None
    on_left, on_right = float(np.mean(np.array(votes) < 0)), float(np.mean(np.array(votes) > 0))
    if max(on_left, on_right) < MIN_AGREEMENT:
        return None
    return OtherLeg("left" if on_left > on_right else "right", len(votes), float(np.median(offsets)))


def other_leg_beside(calf_points: np.ndarray, d_mm: float, pixel_mm: float = 10.0) -> OtherLeg | None:
    """The second leg beside the measured one (module docstring), or None when the scan
    holds none that the rule can see.

    calf_points (n, 3): every point of the cleaned scan in the measured leg's calf frame
    (mm, B at the origin, z up the leg, x the subject's right); ``d_mm`` D's height above
    B; ``pixel_mm`` the occupancy cell, at least twice the scan's point spacing so that a
    ring of skin stays one blob.
    """
    votes: list[float] = []
    offsets: list[float] = []
    for areas, centres in _slabs(calf_points, d_mm + REACH_ABOVE_D_MM, pixel_mm):
        vote = _beside_vote(areas, centres)
        if vote is not None:
            votes.append(vote[0])
            offsets.append(vote[1])
    return _told(votes, offsets, MIN_SLABS)


def other_leg_confirmed(calf_points: np.ndarray, d_mm: float, pixel_mm: float = 10.0) -> OtherLeg | None:
    """A second leg seen well enough to confirm a side another cue told, never to tell it
    alone (module docstring: the upper thigh of a leg cut off above its knee), or None.

    Arguments as :func:`other_leg_beside`'s.  Every slab from B to the scan's top is read,
    up to the first whose filled area is less than half the slab's below (the scan's
    ragged top edge, or a gap), and :data:`CONFIRMING_SLABS` votes suffice.  A slab votes
    as in :func:`other_leg_beside` or, above D, where the measured leg has merged with
    the other (the crotch, the pelvis: the body's midline lies medial to each leg), for
    the side its one blob's centre moved to: a blob of at least 1 + LEG_AREA_SHARE times
    the leg's own section in the last unmerged slab whose centre moved sideways (x) at
    least as far as the centroid of the leg and the least second leg would
    (MIN_APART_MM * LEG_AREA_SHARE / (1 + LEG_AREA_SHARE), 20 mm); a buttock's gradual
    growth behind a single leg moves it back (y), not sideways.
    """
    least_shift = MIN_APART_MM * LEG_AREA_SHARE / (1.0 + LEG_AREA_SHARE)
    votes: list[float] = []
    offsets: list[float] = []
    below_area = 0.0
    leg_area, leg_centre = None, None  # the measured leg's own section in the last unmerged slab
    top = float(calf_points[:, 2].max(initial=0.0))
    for index, (areas, centres) in enumerate(_slabs(calf_points, top, pixel_mm)):
        if below_area > 0.0 and areas.sum() < 0.5 * below_area:
            break
        below_area = float(areas.sum())
        vote = _beside_vote(areas, centres)
        if vote is not None:
            votes.append(vote[0])
            offsets.append(vote[1])
        if not len(areas):
            continue
        own = int(np.argmin(np.linalg.norm(centres, axis=1)))
        shift = float(centres[own, 0] - leg_centre[0]) if leg_centre is not None else 0.0
        merged = (leg_area is not None and (index + 0.5) * SLAB_MM > d_mm and vote is None
                  and areas[own] >= (1.0 + LEG_AREA_SHARE) * leg_area and abs(shift) >= least_shift)
        if merged:
            votes.append(float(np.sign(shift)))
            offsets.append(abs(shift))
        elif vote is None or leg_area is None:
            leg_area, leg_centre = float(areas[own]), centres[own]
    return _told(votes, offsets, CONFIRMING_SLABS)
