"""A point of the leg at a height, read as a tape reads it (RAL-GZ 387's measuring
points): its tape girth on the plane perpendicular to the leg's axis, across a tape's
width, where the tape lies, and how far the girth may be off where the scan leaves the
point's height uncertain.  app.geometry.anatomy.knee_middle (E) and
app.geometry.anatomy.thigh (F, G) read their points through it.

Frame: the calf frame (mm; z up the leg).  Arrays: points (n, 3), faces (f, 3) or None;
heights (k,) rising.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from app.geometry.sections import LimbGraph, PolarSections, tape_band_girths

#: a made-to-measure order's girths are held to this (mm): a point whose height is
#: uncertain by more than this much of its girth is said to be
GIRTH_TOLERANCE_MM = 3.0


@dataclass(frozen=True)
class LevelPoint:
    """A point of the leg at a height: ``girth_mm`` (tape) and ``height_mm`` (calf
    frame), or None with the ``reason``; ``at_mm``: the centre of the tape's section
    (x, y, height), where its plane crosses the limb (the workbench draws the tape there)."""

    name: str
    girth_mm: float | None
    height_mm: float | None
    reason: str | None = None
    at_mm: tuple[float, float, float] | None = None
    #: how far the girth may be off (mm) where the scan leaves the point's place uncertain
    #: by more than GIRTH_TOLERANCE_MM of girth (a knee without a level crown, a smooth
    #: gluteal fold); the record's warnings say why.  None: within the tolerance
    uncertainty_mm: float | None = None
    #: how far the point's height may be off (mm): E's level stretch, G's smooth fold, F
    #: halfway between (app.geometry.anatomy.thigh); the order's lengths (lE, lF, lG) say it
    #: beyond app.geometry.garment.measuring_points.LENGTH_TOLERANCE_MM.  None: not read
    height_uncertainty_mm: float | None = None

    def as_dict(self) -> dict:
        out: dict = {"value_mm": self.girth_mm, "height_mm": self.height_mm, "reason": self.reason}
        if self.at_mm is not None:
            out["at_mm"] = list(self.at_mm)
        if self.uncertainty_mm is not None:
            out["uncertainty_mm"] = self.uncertainty_mm
        if self.height_uncertainty_mm is not None:
            out["height_uncertainty_mm"] = self.height_uncertainty_mm
        return out


def girth_spread(heights: np.ndarray, girths: np.ndarray, at_mm: float, half_mm: float) -> float:
    """How much a tape's girth may change when its point lies anywhere within +-``half_mm``
    of ``at_mm`` (mm): the largest |girth(z) - girth(at)| over the measured ``girths`` (k,)
    at ``heights`` (k,, rising) within that reach and at its ends, read linearly between
    them (held beyond the measured ones; NaN girths are left out).  The girth's slope at
    the point alone understates it where the girth turns within the reach: above a
    smooth gluteal fold (the buttock) or across a knee's crown."""
    measured = np.isfinite(girths)
    z, g = heights[measured], girths[measured]
    if not len(z):
        return 0.0
    inside = z[(z > at_mm - half_mm) & (z < at_mm + half_mm)]
    reach = np.interp(np.r_[at_mm - half_mm, inside, at_mm + half_mm], z, g)
    return float(np.max(np.abs(reach - np.interp(at_mm, z, g))))


def read_across_tape(levels: tuple[LevelPoint, ...], points: np.ndarray, faces: np.ndarray | None,
                     edges: np.ndarray | LimbGraph | None = None) -> tuple[LevelPoint, ...]:
    """Each point's girth read across a tape's width (the median over the planes
    app.geometry.sections.TAPE_BAND_OFFSETS_MM about its height, as B, B1, C, D are:
    one plane spoiled by a scanner's noise or a hole's edge is outvoted), its height and
    centre kept; the single plane's girth where the band has no reading.  The points are
    read in one call: each plane's section depends on its own plane (a mesh's) or slab (a
    cloud's) only, so reading them together gives what reading each alone does.  ``edges``:
    a sparse cloud's neighbour graph (app.geometry.sections.tape_sections)."""
    readable = [i for i, level in enumerate(levels) if level.girth_mm is not None and level.height_mm is not None]
    if not readable:
        return levels
    band = tape_band_girths(points, faces, np.array([levels[i].height_mm for i in readable]), edges)
    read = list(levels)
    for i, girth in zip(readable, band):
        if np.isfinite(girth):
            read[i] = dataclasses.replace(levels[i], girth_mm=float(girth))
    return tuple(read)


def level_on_section(name: str, sections: PolarSections, girths: np.ndarray, index: int) -> LevelPoint:
    """The point ``name`` read on section ``index`` of ``sections`` (its tape girth, of
    ``girths`` (k,) the sections' tape perimeters, and its centre), or not closed there."""
    girth = float(girths[index])
    height = float(sections.heights_mm[index])
    if not np.isfinite(girth):
        return LevelPoint(name, None, None, "the section there is not closed (a hole, or the scan's edge)")
    centre = sections.centroids_mm[index]
    return LevelPoint(name, girth, height, at_mm=(float(centre[0]), float(centre[1]), height))


def level_between(name: str, sections: PolarSections, girths: np.ndarray, height_mm: float) -> LevelPoint:
    """The point ``name`` at ``height_mm``, between two of ``sections`` (evenly spaced):
    its girth and centre read linearly between theirs (a tape's reading across its width,
    :func:`read_across_tape`, then replaces the girth), or not closed there when either
    of the two sections is not."""
    z = sections.heights_mm
    below = int(np.clip(np.searchsorted(z, height_mm, side="right") - 1, 0, len(z) - 2)) if len(z) > 1 else 0
    above = min(below + 1, len(z) - 1)
    t = float(np.clip((height_mm - z[below]) / (z[above] - z[below]), 0.0, 1.0)) if above != below else 0.0
    weights = np.array([1 - t, t])
    pair = girths[[below, above]]
    if not np.isfinite(pair[weights > 0]).all():
        return LevelPoint(name, None, None, "the section there is not closed (a hole, or the scan's edge)")
    centre = weights[weights > 0] @ sections.centroids_mm[[below, above]][weights > 0]
    girth = float(weights[weights > 0] @ pair[weights > 0])
    return LevelPoint(name, girth, float(height_mm), at_mm=(float(centre[0]), float(centre[1]), float(height_mm)))

