"""The stocking's two ends: its foot, knitted from the order form's cY and cA (RAL-GZ 387's
heel-instep diagonal and forefoot girth, measured from the scan by
:mod:`app.geometry.anatomy.foot`), and its top band.

**The foot.**  The standards grade the stocking from B upwards (RAL-GZ 387 and ENV 12718
give the class's pressure at B and the profile above it); none sets a pressure for the
foot.  calf-nurbs knits the foot's rows for B's target: the graduation begins at B, so no
point below it is pressed more (B's pressure is the stocking's highest) or less (a foot
pressed less than the ankle is where the oedema the stocking moves gathers).  Each row is
the calf's step (:func:`app.geometry.garment.knitting.knit_rows`): the stretched
circumference is the tape girth from the scan (the fabric spans the loop's hull), T = P L
/ (2 pi), the strain from the fabric, L0 = L / (1 + eps) rounded, and the prediction
2 pi T / L recomputed from the rounded L0.  The foot's length: a closed toe is knitted to
the measured foot length (heel to the longest toe, ISO 7250-1 5.3.1); an open toe ends
over the metatarsal heads, the toes free (the length heel to cA), the manufacturer's
finishing past it.

**The top band.**  The stocking ends at D (knee-high, AD: the calf record's top, the
knee's waist below the fibular head) or G (thigh-high, AG) with a band
:data:`TOP_BAND_WIDTH_MM` wide, knitted as one tube of one relaxed circumference.  It must
not press more than the graded rows it replaces anywhere across its width - a band
tighter than the leg below it is a tourniquet, the failure the graduation exists to
avoid - so its L0 is the largest L0 of those rows; its pressure across its width (at
each replaced row's stretched circumference) is reported.  A silicone grip is the
manufacturer's finishing and adds friction, not pressure.  The widths are the usual
knitted and silicone bands' (manufacturers' practice, not a standard's).

Units: mm, mmHg reported (Pa inside), N/cm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.garment.fabric import Fabric
from app.geometry.garment.knitting import KnittingSpec, knit_rows
from app.geometry.garment.pressure import PA_PER_MMHG, laplace_mean_pa

#: the top band's width by stocking type, mm (module docstring)
TOP_BAND_WIDTH_MM = {"AD": 25.0, "AG": 50.0}
#: the widest band asked for, mm (a band is a finishing, not a second stocking)
MAX_TOP_BAND_MM = 100.0
TOES = ("closed", "open")


@dataclass(frozen=True)
class FootRow:
    """One knitted row of the foot at ``point`` ("cA" forefoot, "cY" heel-instep): its
    height (the calf frame z of where the tape lies, mm; below B), the target and the
    predicted mean mmHg, the stretched (tape) and relaxed circumferences mm, strain (-),
    tension N/cm."""

    point: str
    height_mm: float
    target_mmhg: float
    predicted_mean_mmhg: float
    stretched_circumference_mm: float
    relaxed_circumference_mm: float
    strain: float
    tension_n_per_cm: float


@dataclass(frozen=True)
class FootPart:
    """The foot: its rows from the toe to the heel (cA, then cY), the measured foot length,
    the length it is knitted to, mm, and the toe."""

    rows: tuple[FootRow, ...]
    toe: str
    foot_length_mm: float | None
    knitted_length_mm: float | None
    length_rule: str


@dataclass(frozen=True)
class TopBand:
    """The top band: from ``from_height_mm`` to ``to_height_mm`` (calf frame), one relaxed
    circumference mm, its predicted mean pressure across its width (min, max) mmHg and the
    graded rows' it replaces (min, max), and which graded rows it replaces (indices into
    the knitting specification)."""

    width_mm: float
    from_height_mm: float
    to_height_mm: float
    relaxed_circumference_mm: float
    band_mmhg: tuple[float, float]
    graded_mmhg: tuple[float, float]
    replaces: np.ndarray  # (r,) int: rows of the specification
    band_pressure_mmhg: np.ndarray  # (r,) the band's mean pressure on each of them
    band_strain: np.ndarray  # (r,) the band's strain on each (-)
    band_tension_n_per_cm: np.ndarray  # (r,) and its tension, N/cm


@dataclass(frozen=True)
class FootOutcome:
    """The foot part, or None with the reason (the scan has no foot, a point is missing)."""

    part: FootPart | None
    reason: str | None = None


def foot_part(chart: dict | None, target_b_mmhg: float, toe: str, fabric: Fabric, resolution_mm: float) -> FootOutcome:
    """The foot (module docstring) from the record's chart {cA, cY, foot_length: {value_mm,
    at_mm, reason}} (schema version 3), or why not.  Raises FitFailure
    UNREACHABLE_PRESSURE when the fabric cannot give B's pressure round the foot."""
    chart = chart or {}
    entry = {p: chart.get(p) or {} for p in ("cA", "cY", "foot_length")}
    missing = [p for p in ("cA", "cY") if entry[p].get("value_mm") is None or not entry[p].get("at_mm")]
    if missing:
        reasons = sorted({str(r) for p in missing if (r := entry[p].get("reason"))})
        why = "; ".join(reasons) if reasons else "the record was made before the foot was measured (schema version 3)"
        return FootOutcome(None, f"the foot's rows need cA and cY, and {', '.join(missing)} is not measured: {why}; "
                                 "take them by tape (RAL-GZ 387)")
    points = ("cA", "cY")  # toe to heel, the order the foot is knitted in from a closed toe
    girth = np.array([float(chart[p]["value_mm"]) for p in points])
    heights = np.array([float(chart[p]["at_mm"][2]) for p in points])
    target = np.full(2, float(target_b_mmhg))
    knitted = knit_rows(heights, target, girth, fabric, resolution_mm, where="on the foot at")
    mean = laplace_mean_pa(knitted.tension_n_per_cm, girth) / PA_PER_MMHG
    rows = tuple(FootRow(p, float(heights[i]), float(target[i]), float(mean[i]), float(girth[i]),
                         float(knitted.relaxed_mm[i]), float(knitted.strain[i]), float(knitted.tension_n_per_cm[i]))
                 for i, p in enumerate(points))
    length_entry = entry["foot_length"]
    length = length_entry.get("value_mm")
    if length is None:
        return FootOutcome(FootPart(rows, toe, None, None, "the foot length is not measured: take it by tape"))
    length = float(length)
    if toe == "closed":
        return FootOutcome(FootPart(rows, toe, length, length, "closed toe: knitted to the foot length, heel to the longest toe"))
    # open: heel to the ball.  The foot length's point is the foot's middle on the foot's
    # axis at the sole, cA's the ball on the same axis (app.geometry.anatomy.foot): the
    # ball lies their horizontal distance ahead of the middle
    middle, ball = np.asarray(length_entry.get("at_mm") or [np.nan] * 3, float), np.asarray(chart["cA"]["at_mm"], float)
    ahead = float(np.hypot(*(ball[:2] - middle[:2])))
    if not np.isfinite(ahead):
        return FootOutcome(FootPart(rows, toe, length, None, "open toe: the ball's place on the foot is not in the record"))
    return FootOutcome(FootPart(rows, toe, length, length / 2 + ahead,
                                "open toe: knitted from the heel to the metatarsal heads (cA), the toes free"))


def top_band(spec: KnittingSpec, width_mm: float, fabric: Fabric) -> TopBand | None:
    """The top band over the specification's top ``width_mm`` (module docstring), or None
    for a width of 0 (no band).  spec: the graded rows, heights rising."""
    if width_mm <= 0:
        return None
    top = float(spec.heights_mm[-1])
    replaces = np.flatnonzero(spec.heights_mm >= top - width_mm - 1e-9)
    relaxed = float(spec.relaxed_circumference_mm[replaces].max())
    stretched = spec.stretched_circumference_mm[replaces]
    strain = np.maximum(stretched / relaxed - 1.0, 0.0)
    tension = fabric.tension(strain)
    band = laplace_mean_pa(tension, stretched) / PA_PER_MMHG
    graded = spec.predicted_mean_pa[replaces] / PA_PER_MMHG
    return TopBand(float(width_mm), float(spec.heights_mm[replaces[0]]), top, relaxed,
                   (float(band.min()), float(band.max())), (float(graded.min()), float(graded.max())), replaces, band,
                   strain, tension)
