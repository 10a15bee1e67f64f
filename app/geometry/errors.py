"""Typed failures of the fitting core.

Every step of the pipeline that cannot go on raises :class:`FitFailure` with a
:class:`FailureReason` (a stable machine-readable code) and a sentence a clinician or
a script can act on.  Nothing in ``app.geometry`` lets a bare numpy/trimesh traceback
escape for bad input: callers (CLI, HTTP service) map the reason to their own error
format exactly once.
"""

from __future__ import annotations

import enum


class FailureReason(str, enum.Enum):
    """Why a scan could not be turned into a calf record."""

    UNREADABLE_FILE = "unreadable_file"
    TRUNCATED_FILE = "truncated_file"
    UNSUPPORTED_FORMAT = "unsupported_format"
    EMPTY_SCAN = "empty_scan"
    NON_FINITE_COORDINATES = "non_finite_coordinates"
    TOO_FEW_POINTS = "too_few_points"
    TOO_SPARSE = "too_sparse"
    SCAN_TOO_LARGE = "scan_too_large"
    IMPLAUSIBLE_SIZE = "implausible_size"
    NOT_A_LEG = "not_a_leg"
    PARTIAL_VIEW = "partial_view"
    NO_ANKLE = "no_ankle"
    NO_KNEE = "no_knee"
    NO_CALF = "no_calf"
    KNEE_BENT = "knee_bent"
    SEVERAL_LEGS = "several_legs"
    SIDE_NOT_FOUND = "side_not_found"
    INVALID_OPTION = "invalid_option"
    DEGENERATE_SURFACE = "degenerate_surface"
    INVALID_RECORD = "invalid_record"
    SURFACE_TOO_COSTLY = "surface_too_costly"
    # garment design
    INVALID_TARGET = "invalid_target"
    INVALID_FABRIC = "invalid_fabric"
    UNREACHABLE_PRESSURE = "unreachable_pressure"
    # size charts
    INVALID_SIZE_CHART = "invalid_size_chart"


class FitFailure(Exception):
    """A scan (or record) that cannot be processed, with the reason.

    Attributes
    ----------
    reason : FailureReason
        Stable code, used as the last path segment of the HTTP problem ``type``.
    detail : str
        Human-readable explanation naming what is wrong with the input.
    """

    def __init__(self, reason: FailureReason, detail: str):
        super().__init__(detail)
        self.reason = FailureReason(reason)
        self.detail = detail
        #: girths (mm, in the unit the scan was read in) of the calf-like bulges the
        #: landmark search found and set aside as on a rising flank (:class:`BulgeOnFlank`):
        #: a placement refusal's evidence of a wrong unit (app.geometry.placement.leg_size)
        self.flank_bulges_mm: tuple[float, ...] = ()

    def __reduce__(self):  # picklable across the worker-process boundary
        return (FitFailure, (self.reason, self.detail))

    def __repr__(self) -> str:  # pragma: no cover - debugging aid
        return f"FitFailure({self.reason.value!r}, {self.detail!r})"


class FootFound(FitFailure):
    """A ``no_calf`` refusal that found a foot where a calf was looked for.

    Positive evidence about the scan (the section there is as long as a foot, not round
    as a calf), so it outranks a refusal that only missed something (``no_ankle``: a
    bulge with no ankle below it) when the two orientations of a scan disagree.
    ``girth_mm``: the girth of the section found to be a foot.  Crosses a process
    boundary as a plain :class:`FitFailure`."""

    def __init__(self, detail: str, girth_mm: float):
        super().__init__(FailureReason.NO_CALF, detail)
        self.girth_mm = float(girth_mm)


class BulgeOnFlank(FitFailure):
    """A ``no_calf`` refusal of a calf candidate whose knee waist would be wider than it:
    the girth keeps rising above it (a sparse cloud's noise bump on the calf's flank; on a
    leg read in too large a unit, the real calf, whose knee waist the millimetre windows
    miss).  ``girth_mm``: the candidate's girth.  Crosses a process boundary as a plain
    :class:`FitFailure`."""

    def __init__(self, detail: str, girth_mm: float):
        super().__init__(FailureReason.NO_CALF, detail)
        self.girth_mm = float(girth_mm)


class CalfWithoutBulge(FitFailure):
    """A ``no_calf`` refusal of a lower leg that stands on its foot but has no ankle waist
    and calf bulge to find B, C and D on: its ankle is nearly as wide as its calf (an
    oedematous or lymphoedematous leg).  Positive evidence about the scan - a foot with
    a leg above it, measured - so it outranks a found foot and a missing ankle, and yields
    only to a candidate that found ankle and calf (a missing knee).  Crosses a process
    boundary as a plain :class:`FitFailure`."""

    def __init__(self, detail: str):
        super().__init__(FailureReason.NO_CALF, detail)


class BridgedStrip(FitFailure):
    """A ``partial_view`` refusal inferred, not measured: no ankle, knee waist or calf was
    found on a profile whose sections miss, on one side, arcs whose bridges may move their
    girths past an order's tolerance (app.geometry.placement.coverage.
    bridged_strip_refusal) - the strip is the likelier cause of the shape refusal.  It
    yields to a knee found bent (``knee_bent``: a shank cut free at a measured bend that
    showed its ankle and calf), whose diagonal sections read through the L look like a
    strip's arcs, and outranks the refusals it re-reads.  Crosses a process boundary as a
    plain :class:`FitFailure`."""

    def __init__(self, detail: str):
        super().__init__(FailureReason.PARTIAL_VIEW, detail)


class JoinedAboveCalf(FitFailure):
    """A ``no_knee`` refusal of a reading that found the ankle and the calf and, above
    the calf while the leg still narrows, another body part joining the sections (the
    girth up 25% within 5 mm: the thigh of a bent knee, the other leg, a hand;
    app.geometry.anatomy.calf_candidates.merged_above).  It outranks a partial view
    inferred from arcs (:class:`BridgedStrip`, a guess: a join read through diagonal
    sections looks like a strip's arcs) and yields to a knee found bent.  ``over_join``:
    the bulge read as the calf lies above the join (its sections are not the leg's
    alone; the "ankle" under it may be the leg narrowing into the join).  Crosses a
    process boundary as a plain :class:`FitFailure`."""

    def __init__(self, detail: str, over_join: bool = False):
        super().__init__(FailureReason.NO_KNEE, detail)
        self.over_join = over_join


class RisesToEdge(FitFailure):
    """A ``no_knee`` (``no_ankle``) refusal of a profile that only rises to the scan's
    top (bottom) edge: no ankle and no calf maximum were found, only a girth growing
    towards an edge.  The weakest evidence of where the scan stops (a thigh cut free at a
    bent knee rises so too), so it yields to any reading that found a calf bulge."""
