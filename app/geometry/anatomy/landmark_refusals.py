"""How a calf candidate's refusal reads, and how far it got (app.geometry.anatomy.landmarks).

Every refusal names what is missing from the scan and how to scan again; a candidate's
stage (:func:`failure_stage`) says which of several refusals tells the most.  Units: mm.
"""

from __future__ import annotations

from app.geometry.errors import (
    BridgedStrip,
    CalfWithoutBulge,
    FailureReason,
    FitFailure,
    FootFound,
    JoinedAboveCalf,
    RisesToEdge,
)

#: how far a candidate got before it failed (higher is more informative)
#: (a leg seen from one side, app.geometry.placement.coverage, is the most informative:
#: whatever another axis or a bent knee's runs then find or miss is read off a half leg)
#: (a bent knee's shank that showed its ankle and calf, its knee waist under the thigh,
#: tells more than a knee waist missing from a straight reading)
FAILURE_STAGE = {FailureReason.NOT_A_LEG: 0, FailureReason.NO_CALF: 0, FailureReason.NO_ANKLE: 1, FailureReason.NO_KNEE: 2,
                 FailureReason.KNEE_BENT: 2.5, FailureReason.PARTIAL_VIEW: 3}


def failure_stage(failure: FitFailure) -> float:
    """How informative a candidate's refusal is: :data:`FAILURE_STAGE`, and a found foot
    (:class:`FootFound`) between a missing ankle and a missing knee (it identified the
    bulge; a missing ankle only did not find one below it; a missing knee found both), a
    leg without a calf bulge above its foot (:class:`CalfWithoutBulge`) above a found foot
    (it measured the foot and the leg on it); a girth that only rises to an edge
    (:class:`RisesToEdge`) below a missing ankle; a partial view inferred from a shape
    refusal (:class:`BridgedStrip`) above a missing knee and below a knee found bent
    (robustness 220 7, seated-04: a knee bent 90 degrees read along the L's diagonal has
    sections whose arcs read like a strip's); a join above a narrowing calf
    (:class:`JoinedAboveCalf`) between that partial view and a knee found bent (robustness
    220 23, seated-04: the thigh joins the shank's sections under its knee waist, and
    the diagonal reading's arcs were all that was left to say); of two joins, the one
    under the leg's own calf above one read from a bulge over its join
    (:attr:`JoinedAboveCalf.over_join`: the other body part's bulge, its "ankle" the leg
    narrowing into the join - a join at 350 mm over an ankle at 38 was named "12 mm above
    the ankle" from the thigh's larger bulge, "64 mm above the calf maximum" from the
    leg's own, which came first hanging on a rounding)."""
    if isinstance(failure, JoinedAboveCalf):
        return 2.35 if failure.over_join else 2.4
    if isinstance(failure, BridgedStrip):
        return 2.25
    if isinstance(failure, CalfWithoutBulge):
        return 1.75
    if isinstance(failure, FootFound):
        return 1.5
    if isinstance(failure, RisesToEdge):
        return 0.5
    return FAILURE_STAGE.get(failure.reason, 0)


#: what a knee_bent refusal asks of the clinic
SCAN_STRAIGHT = "Scan the leg standing, or lying with the knee straight, as a compression stocking is measured."


def no_ankle(span_mm: float) -> FitFailure:
    return FitFailure(
        FailureReason.NO_ANKLE,
        "the ankle (B, the narrowest part of the lower leg above the ankle bones) is not in the "
        f"scan: the scan reaches {span_mm:.0f} mm below the calf maximum, where the leg is still "
        "narrowing. Re-scan from below the ankle bones (best: include the heel and foot).",
    )


def no_knee(span_mm: float) -> FitFailure:
    return FitFailure(
        FailureReason.NO_KNEE,
        "the knee waist (D, the narrowest part of the leg below the knee) is not in the scan: the "
        f"scan reaches {span_mm:.0f} mm above the calf maximum, where the leg is still narrowing. "
        "Re-scan up to at least 3 cm above the knee joint (over the kneecap).",
    )


def knee_unreadable(at_mm: float, rise: float, above: str = "the calf maximum") -> FitFailure:
    """The leg's sections widen by ``rise`` (a fraction) within a few mm ``at_mm`` above
    ``above`` (the calf maximum, or the ankle) while the leg below still narrows or has
    no knee waist: another body part joins them, and the knee waist lies among sections
    that are not the leg's alone.  Read from the ankle, the join lies under the bulge
    taken for the calf (:attr:`JoinedAboveCalf.over_join`)."""
    return JoinedAboveCalf(
        "the knee waist (D, the narrowest part of the leg below the knee) could not be found: "
        f"{at_mm:.0f} mm above {above} the leg's cross-sections widen by {100 * rise:.0f}% within a few "
        "millimetres - another body part joins them there (the thigh of a bent knee, the other leg, a hand) - "
        "and below that the leg has no knee waist. Scan the leg standing, with the other leg and the hands clear "
        "of it from the ankle to above the knee.",
        over_join=above == "the ankle",
    )


def lost_inside_window(failure: FitFailure, window_mm: tuple[float, float], scan_mm: tuple[float, float],
                       tilt_deg: float) -> FitFailure:
    """``failure`` of the landmarks found again on a profile cut to ``window_mm`` (low,
    high; the calf's own axis, ``tilt_deg`` from the axis they were first found along),
    said as what it is when the scan (``scan_mm``: its extent along that axis) goes on
    past the window's end the failure names: not "the scan reaches ... mm" (the window's
    end, not the scan's) but a landmark lost along the new axis.  Same class and reason,
    so the refusals rank as before (:func:`failure_stage`); other failures as they are."""
    knee = failure.reason is FailureReason.NO_KNEE
    if not (knee or failure.reason is FailureReason.NO_ANKLE) or isinstance(failure, JoinedAboveCalf):
        return failure  # (a join says what lies in the window's sections, not where the window ends)
    if (scan_mm[1] <= window_mm[1]) if knee else (scan_mm[0] >= window_mm[0]):
        return failure
    what = ("the knee waist (D, the narrowest part of the leg below the knee)" if knee else
            "the ankle (B, the narrowest part of the lower leg above the ankle bones)")
    return type(failure)(
        failure.reason,
        f"{what} was not found again along the calf's own axis ({tilt_deg:.0f} degrees from the axis it was first "
        f"found along), though the scan goes on past it: the leg may be bent or twisted there, or not scanned all "
        f"round. Scan the leg standing straight and all round, from below the ankle bones to 3 cm above the knee.")


def ends_inside_calf(rise_mm: float, low_mm: float, high_mm: float, at_top: bool) -> FitFailure:
    """The scan stops while the girth is still rising towards the calf: no calf maximum,
    and the waist beyond it, in the scan.  ``rise_mm``: from the narrowest section to
    the scan's edge, over which the girth rises from ``low_mm`` to ``high_mm``."""
    if at_top:
        return RisesToEdge(
            FailureReason.NO_KNEE,
            f"the scan ends inside the calf: from its narrowest section the girth rises {rise_mm:.0f} mm up to the "
            f"scan's top edge ({low_mm:.0f} to {high_mm:.0f} mm) without reaching the calf maximum, so the calf "
            "maximum C and the knee waist D above it are not in the scan. Re-scan up to at least 3 cm above the "
            "knee joint (over the kneecap).")
    return RisesToEdge(
        FailureReason.NO_ANKLE,
        f"the scan starts inside the calf: from its narrowest section the girth rises {rise_mm:.0f} mm down to the "
        f"scan's bottom edge ({low_mm:.0f} to {high_mm:.0f} mm), so the ankle B below the calf is not in the scan. "
        "Re-scan from below the ankle bones (best: include the heel and foot).")


def no_calf(detail: str) -> FitFailure:
    return FitFailure(
        FailureReason.NO_CALF,
        f"{detail}. The scan must hold the whole lower leg: from below the ankle bones to above "
        "the knee joint, with the calf in between.",
    )


def calf_without_bulge(detail: str) -> CalfWithoutBulge:
    """A lower leg on its foot without an ankle waist and calf bulge (``detail`` says what
    was measured): what it is, and what to do instead of scanning again."""
    return CalfWithoutBulge(
        f"{detail}. A lower leg nearly as wide at the ankle as at the calf (oedema, lymphoedema, a wasted "
        "calf) has no ankle waist and calf bulge for the landmarks B, C and D to be found on, and scanning it "
        "again will not give them: take its measurements by tape at the order form's points.")
