"""Is the placed leg the size of a human leg?  The unit check after placement.

The scan's unit is detected from its extent (:func:`app.geometry.scan.reader.detect_units`),
which cannot tell a leg in inches from one in centimetres (a 16-inch lower leg reads
as a 160 mm one).  Once the calf is found, its girth at C says more: ANSUR II (6,068
US Army adults, 2012; ``tests/data/ansur2``) measured calf circumferences of
266-523 mm.  A calf is refused when its tape girth at C lies outside
[:data:`MIN_CALF_GIRTH_MM`, :data:`MAX_CALF_GIRTH_MM`] = [266 / 1.25, 523 x 1.6] mm: the
lower margin admits adolescents and slight adults; the upper, lymphoedema and obese
legs up to 837 mm; and the band is narrow enough that no ANSUR calf in inches read as
cm (at most 523 / 2.54 = 206 mm) or in cm read as mm, or in mm read as cm, falls in it.
Children's legs (under ~210 mm at the calf) are outside this service's range.

The refusal names the unit that would make the calf most plausible: of mm, cm, m and
inches, the one that puts the girth inside the band and closest (in ratio) to the
ANSUR II median of 385 mm.  A girth outside the band that no other unit explains is
not refused here (a seated scan's thigh folded onto the calf reads 880 mm): units are
not its problem, and the fit's own checks name what is.  Units: mm.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from app.geometry.errors import FailureReason, FitFailure, FootFound
from app.geometry.scan.reader import UNIT_SCALE_MM

ANSUR_CALF_GIRTH_MM = (266.0, 385.0, 523.0)  # min, median, max
MIN_CALF_GIRTH_MM = ANSUR_CALF_GIRTH_MM[0] / 1.25
MAX_CALF_GIRTH_MM = ANSUR_CALF_GIRTH_MM[2] * 1.6
#: half-height of the slab of points whose hull is the girth at C (mm)
SLAB_MM = 3.0
UNIT_NAMES = {"mm": "millimetres", "cm": "centimetres", "m": "metres", "in": "inches"}


def calf_girth_mm(points_calf: np.ndarray, c_mm: float) -> float | None:
    """Tape girth (convex-hull perimeter, mm) of the calf-frame points (n, 3) within
    :data:`SLAB_MM` of the height ``c_mm``; None when too few points lie there."""
    slab = points_calf[np.abs(points_calf[:, 2] - c_mm) <= SLAB_MM, :2]
    if len(slab) < 8:
        return None
    try:
        return float(ConvexHull(slab).area)  # in 2-D, "area" is the perimeter
    except QhullError:
        return None


def likeliest_unit(girth_mm: float, unit: str) -> tuple[str, float] | None:
    """The unit (and the girth it would give, mm) that makes a calf read as ``girth_mm``
    in ``unit`` most plausible, or None when none puts it inside the band."""
    best = None
    for other, scale in UNIT_SCALE_MM.items():
        girth = girth_mm * scale / UNIT_SCALE_MM[unit]
        if other != unit and MIN_CALF_GIRTH_MM <= girth <= MAX_CALF_GIRTH_MM:
            score = abs(np.log(girth / ANSUR_CALF_GIRTH_MM[1]))
            if best is None or score < best[0]:
                best = (score, other, girth)
    return None if best is None else (best[1], best[2])


def _size_refusal(girth: float, unit: str, unit_detected: bool, what: str) -> FitFailure | None:
    """The ``implausible_size`` refusal of a calf ``girth`` mm round as read in ``unit``
    (``what`` says where it was measured), or None when it is a human calf's or no other
    unit makes it one: not a question of units (a thigh folded onto the calf of a seated
    scan, a bandaged leg); the fit's own checks say what is wrong."""
    if MIN_CALF_GIRTH_MM <= girth <= MAX_CALF_GIRTH_MM:
        return None
    other = likeliest_unit(girth, unit)
    if other is None:
        return None
    how = "detected from the scan's extent" if unit_detected else "as given"
    read = f"read in {UNIT_NAMES.get(unit, unit)} ({how})"
    detail = (f"the calf measures {girth:.0f} mm round {what}, {read}; a human calf is "
              f"{MIN_CALF_GIRTH_MM:.0f}-{MAX_CALF_GIRTH_MM:.0f} mm round (ANSUR II adults, with a margin)")
    detail += (f". The file is most likely in {UNIT_NAMES[other[0]]} (the calf would then be {other[1]:.0f} mm "
               f"round): upload it again with units={other[0]}")
    return FitFailure(FailureReason.IMPLAUSIBLE_SIZE, detail)


def check_leg_size(points_calf: np.ndarray, c_mm: float, unit: str, unit_detected: bool) -> None:
    """Refuse (``implausible_size``) a calf whose girth at C fits no human leg in ``unit``."""
    girth = calf_girth_mm(points_calf, c_mm)
    refusal = None if girth is None else _size_refusal(girth, unit, unit_detected, "at its widest")
    if refusal is not None:
        raise refusal


#: the shortest scan that can hold a lower leg from below the ankle to above the knee:
#: the landmark rules need B at least 100 mm below C and D 30 mm above it, and adult
#: lower legs measure ~300-480 mm from the ankle to the knee (ANSUR II's lateral
#: malleolus to tibiale heights), so 250 mm leaves room for the shortest
MIN_LOWER_LEG_SCAN_MM = 250.0
#: the longest scan the service accepts (a whole body), mm
MAX_BODY_SCAN_MM = 2500.0
#: the girth of a foot's section along it (the ball of the foot to the heel-instep
#: diagonal): ANSUR II adults' ball-of-foot circumferences are ~200-290 mm and the
#: heel-ankle girth reaches ~370 mm; with margins for children's and swollen feet
FOOT_GIRTH_MM = (160.0, 450.0)
#: refusals about the leg's shape that a wrong unit also produces
SHAPE_REASONS = (FailureReason.NO_ANKLE, FailureReason.NO_KNEE, FailureReason.NO_CALF, FailureReason.NOT_A_LEG,
                 FailureReason.PARTIAL_VIEW, FailureReason.SIDE_NOT_FOUND, FailureReason.TOO_FEW_POINTS,
                 FailureReason.TOO_SPARSE)


def with_unit_hint(failure: FitFailure, extent_mm: float, unit: str, unit_detected: bool) -> FitFailure:
    """``failure`` with a sentence naming the unit that would make the scan a leg.

    A scan read in the wrong unit fails on its shape (a body in cm read as mm is 170 mm
    long: no ankle, calf and knee fit in it), and the shape's refusal alone misleads.
    When the scan's largest extent (``extent_mm``, as read in ``unit``) is shorter than
    :data:`MIN_LOWER_LEG_SCAN_MM` and another unit makes it 250-2,500 mm long (a lower
    leg to a whole body), that unit is named (of several, the one closest in ratio to a
    700 mm leg scan).  Not when the refusal found a foot of a foot's size
    (:class:`FootFound`, girth within :data:`FOOT_GIRTH_MM`): such a foot in the unit
    read is itself evidence the unit is right.  Before that, whatever its length: the
    ``implausible_size`` refusal the calf-like bulges it set aside tell
    (:func:`_flank_unit_refusal`).  Otherwise ``failure`` unchanged.
    """
    if failure.reason not in SHAPE_REASONS:
        return failure
    by_bulges = _flank_unit_refusal(failure, unit, unit_detected)
    if by_bulges is not None:
        return by_bulges
    foot_sized = isinstance(failure, FootFound) and FOOT_GIRTH_MM[0] <= failure.girth_mm <= FOOT_GIRTH_MM[1]
    if extent_mm >= MIN_LOWER_LEG_SCAN_MM or foot_sized:
        return failure
    best = None
    for other, scale in UNIT_SCALE_MM.items():
        length = extent_mm * scale / UNIT_SCALE_MM[unit]
        if other != unit and MIN_LOWER_LEG_SCAN_MM <= length <= MAX_BODY_SCAN_MM:
            score = abs(np.log(length / 700.0))
            if best is None or score < best[0]:
                best = (score, other, length)
    if best is None:
        return failure
    how = "detected from its extent" if unit_detected else "as given"
    detail = (f"{failure.detail.rstrip('.')}. Read in {UNIT_NAMES.get(unit, unit)} ({how}) the scan is only "
              f"{extent_mm:.0f} mm long, shorter than any lower leg from ankle to knee ({MIN_LOWER_LEG_SCAN_MM:.0f} mm "
              f"or more); in {UNIT_NAMES[best[1]]} it would be {best[2]:.0f} mm long: if the file is in "
              f"{UNIT_NAMES[best[1]]}, upload it again with units={best[1]}")
    return FitFailure(failure.reason, detail)


def _flank_unit_refusal(failure: FitFailure, unit: str, unit_detected: bool) -> FitFailure | None:
    """The ``implausible_size`` refusal a placement's shape ``failure`` hides, or None.

    The landmark rules' windows are millimetres: on a leg read in too large a unit (a leg
    in inches read as cm, 2.54 times too small) the knee waist lies closer above the calf
    than D's window starts, the real calf is set aside as a bulge on a rising flank
    (:class:`app.geometry.errors.BulgeOnFlank`) and the refusal that remains names a
    missing knee.  When the calf-like bulges so set aside (``failure.flank_bulges_mm``,
    their girths on the placement's coarse profile) are all outside a human calf's band
    and another unit puts the largest of them in it, that unit is the refusal."""
    bulges = failure.flank_bulges_mm
    if not bulges:
        return None
    if any(MIN_CALF_GIRTH_MM <= girth <= MAX_CALF_GIRTH_MM for girth in bulges):
        return None
    return _size_refusal(max(bulges), unit, unit_detected, "at the largest bulge found below the knee")
