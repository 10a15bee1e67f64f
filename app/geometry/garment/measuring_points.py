"""The measuring points of a made-to-measure compression stocking order, as RAL-GZ 387
(Guetezeichen medizinische Kompressionsstruempfe, measuring instructions) names them and
the manufacturers' order forms follow it: circumferences c (a tape around the limb,
perpendicular to its axis) and lengths l from the floor (the sole plane), in mm.

    cA   forefoot, over the metatarsal heads          (AD, AG)
    cY   heel-instep diagonal, over heel and instep   (AD, AG)
    cB   ankle, at its narrowest, above the malleoli  (AD, AG)
    cB1  where the Achilles tendon meets the calf     (AD, AG)
    cC   calf, at its largest                         (AD, AG)
    cD   below the knee, under the fibula's head      (AD, AG)
    cE   middle of the knee                           (AG)
    cF   middle of the thigh                          (AG)
    cG   top of the thigh, below the gluteal fold     (AG)
    lB .. lG  the heights of those points from the floor; foot length heel to longest toe

A record of the paper's calf model (B to D, section 2) measures cB, cB1, cC, cD, and their
lengths from the floor when the sole is in the scan; a version-3 record also the foot
length, cA and cY (app.geometry.anatomy.foot) when the foot is in the scan, and cE, cF,
cG with their lengths (app.geometry.anatomy.thigh) when the thigh is;
:func:`chart_of_record` reports every other point as not measured, with the reason, so an
order never leaves a blank unexplained.
"""

from __future__ import annotations

from dataclasses import dataclass

from app.geometry.anatomy.feature_layers import HIGH_CONFIDENCE_MM

#: a length whose point's height the scan places less sharply than this (mm: a landmark's
#: ``height_tolerance_mm``, app.geometry.anatomy.feature_layers.height_tolerances - a flat
#: calf crown, a long knee waist; the thigh's points' ``height_uncertainty_mm``) carries
#: that as its uncertainty.  10 mm is the reproducibility of a measuring point placed by
#: hand on the skin (HIGH_CONFIDENCE_MM, ~1 cm in anthropometric practice): within it a
#: length is as sure as a tape's; beyond it a tape anywhere along the stretch reads the
#: girth alike but the length differs by as much (the Visible Human female's calf read from
#: 4,000-40,000 points of its skin: lC 5-11 mm off the mesh's reading, C's tolerance 15-31
#: mm, unsaid before)
LENGTH_TOLERANCE_MM = HIGH_CONFIDENCE_MM

#: stocking types and the leg they cover
STOCKING_TYPES = {"AD": "knee-high (AD): foot to below the knee", "AG": "thigh-high (AG): foot to the top of the thigh"}
TOES = ("closed", "open")


@dataclass(frozen=True)
class MeasuringPoint:
    """One point of the order form: ``name`` (cB, lC, foot_length), ``kind``
    ("circumference" or "length"), what it is, and the stocking types that need it."""

    name: str
    kind: str
    description: str
    needed_for: tuple[str, ...]


MEASURING_POINTS: tuple[MeasuringPoint, ...] = (
    MeasuringPoint("cA", "circumference", "forefoot over the metatarsal heads", ("AD", "AG")),
    MeasuringPoint("cY", "circumference", "heel-instep diagonal", ("AD", "AG")),
    MeasuringPoint("cB", "circumference", "ankle at its narrowest, above the malleoli", ("AD", "AG")),
    MeasuringPoint("cB1", "circumference", "where the Achilles tendon meets the calf muscle", ("AD", "AG")),
    MeasuringPoint("cC", "circumference", "calf at its largest", ("AD", "AG")),
    MeasuringPoint("cD", "circumference", "below the knee, under the head of the fibula", ("AD", "AG")),
    MeasuringPoint("cE", "circumference", "middle of the knee", ("AG",)),
    MeasuringPoint("cF", "circumference", "middle of the thigh", ("AG",)),
    MeasuringPoint("cG", "circumference", "top of the thigh, below the gluteal fold", ("AG",)),
    MeasuringPoint("foot_length", "length", "heel to the tip of the longest toe", ("AD", "AG")),
    MeasuringPoint("lB", "length", "floor to B", ("AD", "AG")),
    MeasuringPoint("lB1", "length", "floor to B1", ("AD", "AG")),
    MeasuringPoint("lC", "length", "floor to C", ("AD", "AG")),
    MeasuringPoint("lD", "length", "floor to D", ("AD", "AG")),
    MeasuringPoint("lE", "length", "floor to E", ("AG",)),
    MeasuringPoint("lF", "length", "floor to F", ("AG",)),
    MeasuringPoint("lG", "length", "floor to G", ("AG",)),
)

#: the calf record's landmarks (paper section 2) and the chart points they give
CALF_POINTS = ("B", "B1", "C", "D")


@dataclass(frozen=True)
class MeasuredPoint:
    """A measuring point on a record: ``value_mm`` (None when not measured, with the
    ``reason``), its height along the limb in the calf frame (mm above the frame's origin,
    None for a point not on the calf axis) and whether the stocking type needs it."""

    point: MeasuringPoint
    value_mm: float | None
    height_mm: float | None
    needed: bool
    reason: str | None = None
    at_mm: tuple[float, float, float] | None = None  # where the tape lies (the foot's and thigh's points), calf frame
    #: how far a girth may be off where the scan leaves its place uncertain (the chart's
    #: uncertainty_mm: a knee without a level crown, a smooth gluteal fold) or misses an
    #: arc of its skin (a calf landmark's girth_uncertainty_mm) or leaves a foot's loop
    #: too sparse to follow it (cA, cY: app.geometry.anatomy.foot), or a length where its
    #: point's height is uncertain by more than LENGTH_TOLERANCE_MM, mm
    uncertainty_mm: float | None = None


#: the record's points off the calf (its ``chart``, version 3): the foot's and the thigh's
FOOT_POINTS = ("foot_length", "cA", "cY")
THIGH_POINTS = ("cE", "cF", "cG")


def chart_of_record(landmarks: dict, sole_mm: float | None, stocking_type: str,
                    foot: dict | None = None, no_sole_reason: str | None = None) -> tuple[MeasuredPoint, ...]:
    """Every measuring point of the order form for a calf record.

    landmarks: name -> {"height_mm", "circumference_mm", "tape_girth_mm"?} for B, B1, C, D
    (calf frame, mm); sole_mm: the sole plane's height in that frame (None when the foot is
    not in the scan); stocking_type: "AD" or "AG".  Girths are the tape girths (the convex
    hull of the section: a tape bridges the concavities, RAL-GZ 387's "Umfang" taken with a
    tape); lengths are heights above the sole plane.  ``foot``: the record's chart
    {foot_length, cA, cY: {value_mm, at_mm, reason}, cE, cF, cG: {value_mm, height_mm,
    at_mm (the section's centre; absent in records made before it was kept), reason}}
    (None: a record before version 3); ``no_sole_reason``: why a scan with its foot in it
    has no sole (the record's scan.sole_reason), said of every length."""
    if stocking_type not in STOCKING_TYPES:
        raise ValueError(f"stocking type must be one of {', '.join(STOCKING_TYPES)}")
    no_floor = no_sole_reason or "the sole is not in the scan, so there is no floor to measure from"
    measured = []
    for point in MEASURING_POINTS:
        needed = stocking_type in point.needed_for
        letter = point.name[1:]
        entry = landmarks.get(letter) if letter in CALF_POINTS else None
        if letter in ("E", "F", "G"):
            level = (foot or {}).get(f"c{letter}")
            if level is None:
                measured.append(MeasuredPoint(point, None, None, needed, "the record was made before the thigh was "
                                              "measured (schema version 3): fit the scan again, or take it by tape"))
                continue
            height = level.get("height_mm")
            if point.kind == "circumference":
                at = level.get("at_mm")
                measured.append(MeasuredPoint(point, level.get("value_mm"), height, needed, level.get("reason"),
                                              None if at is None else (float(at[0]), float(at[1]), float(at[2])),
                                              level.get("uncertainty_mm")))
            elif height is None:
                measured.append(MeasuredPoint(point, None, None, needed, level.get("reason")))
            elif sole_mm is None:
                measured.append(MeasuredPoint(point, None, height, needed, no_floor))
            else:
                measured.append(MeasuredPoint(point, float(height) - float(sole_mm), height, needed,
                                              uncertainty_mm=_length_uncertainty(level.get("height_uncertainty_mm"))))
        elif point.name in FOOT_POINTS:
            measured_foot = (foot or {}).get(point.name)
            if measured_foot is None:
                measured.append(MeasuredPoint(point, None, None, needed, "the record was made before the foot was "
                                              "measured (schema version 3): fit the scan again, or take it by tape"))
            else:
                at = measured_foot.get("at_mm")
                where = None if at is None else (float(at[0]), float(at[1]), float(at[2]))
                measured.append(MeasuredPoint(point, measured_foot.get("value_mm"), None if at is None else float(at[2]),
                                              needed, measured_foot.get("reason"), where, measured_foot.get("uncertainty_mm")))
        elif entry is not None and point.kind == "circumference":
            girth = entry.get("tape_girth_mm", entry.get("circumference_mm"))
            measured.append(MeasuredPoint(point, float(girth), float(entry["height_mm"]), needed,
                                          uncertainty_mm=entry.get("girth_uncertainty_mm")))
        elif entry is not None and sole_mm is not None:
            measured.append(MeasuredPoint(point, float(entry["height_mm"]) - float(sole_mm), float(entry["height_mm"]), needed,
                                          uncertainty_mm=_length_uncertainty(entry.get("height_tolerance_mm"))))
        elif entry is not None:
            measured.append(MeasuredPoint(point, None, float(entry["height_mm"]), needed, no_floor))
        elif letter in CALF_POINTS:
            measured.append(MeasuredPoint(point, None, None, needed, f"the record has no landmark {letter}"))
        else:
            measured.append(MeasuredPoint(point, None, None, needed,
                                          "the calf record models the leg from B to D (paper section 2); "
                                          "this point is not measured from the scan: take it by tape"))
    return tuple(measured)


def _length_uncertainty(height_uncertainty_mm) -> float | None:
    """A length's uncertainty (mm): its point's height uncertainty when more than
    LENGTH_TOLERANCE_MM, else None (within what an order holds lengths to; a record made
    before the uncertainty was kept has none)."""
    if height_uncertainty_mm is None or not height_uncertainty_mm > LENGTH_TOLERANCE_MM:
        return None
    return float(height_uncertainty_mm)
