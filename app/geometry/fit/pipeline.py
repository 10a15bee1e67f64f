"""The paper's pipeline end to end: scan -> calf frame -> sections -> landmarks ->
feature points -> NURBS surface -> error index (sections 2.1-2.6), and the order form's
points off the calf.

:func:`fit_scan` returns a :class:`FitResult` or raises :class:`FitFailure` with the
reason.  Everything is in millimetres; the calf frame is described in
:mod:`app.geometry.placement.calf_frame`.  Finding the leg and placing the calf frame (clean-up,
several legs, bent knees, landmarks at the scan's edge, the side) is
:mod:`app.geometry.placement.place`; this module is the pipeline after it:
:func:`fit_placed_leg` fits the calf (:func:`app.geometry.fit.calf.fit_calf`, sections
2.1-2.6; a calf a bent knee's thigh spoiled is refused as ``knee_bent``), then measures
the sole, the foot and the thigh and models the leg from the ankle up.
"""

from __future__ import annotations

import dataclasses
import time

from app.geometry.anatomy.foot import foot_measures
from app.geometry.anatomy.sole import find_sole
from app.geometry.anatomy.thigh import bent_knee_refusal, thigh_measures
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.fit.calf import MAX_ERROR_POINTS, fit_calf
from app.geometry.fit.leg_model import leg_model_of
from app.geometry.fit.options import FitOptions
from app.geometry.fit.result import FitResult
from app.geometry.fit.sparse_clouds import knee_waist_on_graph, sparse_cloud_graph
from app.geometry.placement.leg_placement import LegPlacement, PlacedLeg
from app.geometry.placement.place import place_leg, replace_leg
from app.geometry.scan.reader import Scan

__all__ = ["MAX_ERROR_POINTS", "FitOptions", "FitResult", "check_scan", "fit_calf", "fit_placed_leg", "fit_scan", "place_scan"]


def fit_scan(scan: Scan, options: FitOptions | None = None, placement: LegPlacement | None = None) -> FitResult:
    """Fit the paper's NURBS calf model to a scan (see module docstring).

    ``placement`` (from :func:`check_scan` on the same scan and options) skips the search
    for the leg, its axis and its landmarks; the result is the same.  It crosses process
    and storage boundaries as JSON (:meth:`LegPlacement.to_dict`), serialised by the
    service layer only.
    """
    options = options or FitOptions()
    options.validate()
    started = time.perf_counter()
    if placement is not None:
        leg = replace_leg(scan, placement)
    else:
        leg = place_leg(scan, options.side)
    return fit_placed_leg(leg, len(scan.points_mm), options, placing_s=time.perf_counter() - started)


def fit_placed_leg(leg: PlacedLeg, n_scan_points: int, options: FitOptions | None = None,
                   placing_s: float = 0.0) -> FitResult:
    """:func:`fit_scan` after the leg is placed: ``leg`` is what :func:`place_scan` (or
    :func:`app.geometry.placement.replace_leg`) cut out of a scan of ``n_scan_points``
    points (scan mm: points (n, 3), faces (f, 3) or None).  ``placing_s`` is the time the
    placement took (the result's ``calf_frame`` stage)."""
    options = options or FitOptions()
    options.validate()
    where = leg.placement
    local = where.frame.to_calf(leg.points)
    graph = sparse_cloud_graph(local, leg.faces, where.d_mm)
    slabs_where = where
    if graph is not None and not where.d_at_window_edge:  # a sparse cloud's D read again on its graph
        d_mm, at_edge = knee_waist_on_graph(local, graph, where.d_mm, where.d_at_scan_edge, where.c_mm)
        where = dataclasses.replace(where, d_mm=d_mm, d_at_scan_edge=at_edge)

    def calf_at(at: LegPlacement) -> FitResult:
        try:
            return fit_calf(local, leg.faces, at.c_mm, at.d_mm, options, placement=at, n_scan_points=n_scan_points,
                            graph=graph)
        except FitFailure as failure:
            # a knee bent but read straight: its thigh in the calf's planes is the cause,
            # not a view from one side (a leg cut free of its thigh, half_spaces, has none)
            said = failure if at.half_spaces else bent_knee_refusal(failure, local, leg.faces, at.d_mm, graph)
            if said is failure:
                raise
            raise said from failure

    try:
        result = calf_at(where)
    except FitFailure as failure:
        # D's layer has no sections above it to bridge it from: where the graph's D is a
        # slab too sparse to close, the slabs' own D (1.4 points per mm: a body's 7k vertices)
        if where is slabs_where or failure.reason is not FailureReason.TOO_SPARSE:
            raise
        where = slabs_where
        result = calf_at(where)
    result.timings["calf_frame"] = placing_s
    # the order form's points off the calf (foot length, cA, cY; cE, cF, cG), or why not
    measuring = time.perf_counter()
    if where.anterior_cue == "foot":
        # the foot is in the scan (it told front from back): the heel's lowest skin is the
        # sole, the floor a standing person's heights are measured from (ISO 8559-1), when
        # the scan reaches under the heel and the foot stands flat (app.geometry.anatomy.sole)
        sole = find_sole(local, leg.faces)
        result = dataclasses.replace(result, sole_mm=sole.height_mm, sole_reason=sole.reason)
    thigh = thigh_measures(local, leg.faces, result.landmarks.D.height_mm, bool(where.half_spaces), graph, where.side)
    foot = foot_measures(local, leg.faces, result.sole_mm, result.sole_reason)
    result = dataclasses.replace(result, foot=foot, thigh=thigh,
                                 fit_warnings=result.fit_warnings + foot.warnings + thigh.warnings)
    result.timings["chart_points"] = time.perf_counter() - measuring
    modelling = time.perf_counter()
    result = dataclasses.replace(result, leg_model=leg_model_of(local, leg.faces, result.landmarks, result.thigh))
    result.timings["leg_model"] = time.perf_counter() - modelling
    return result


def check_scan(scan: Scan, options: FitOptions | None = None) -> LegPlacement:
    """Quick acceptance test of a scan: the options are valid and the calf can be placed
    (the leg found, B, C and D present).  Raises FitFailure with the reason otherwise;
    returns the placement, which :func:`fit_scan` reuses (one placement per upload).
    Costs the calf-frame stage of a fit."""
    return place_scan(scan, options).placement


def place_scan(scan: Scan, options: FitOptions | None = None) -> PlacedLeg:
    """:func:`check_scan` with the leg it cut out: :func:`fit_placed_leg` fits it without
    reading, cleaning or splitting the scan again."""
    options = options or FitOptions()
    options.validate()
    return place_leg(scan, options.side)
