"""Finding the leg in a scan and placing its calf frame (paper section 2.1).

One room for everything between a loaded scan and the calf frame; :func:`place_leg`
returns a :class:`PlacedLeg` (the leg's points and faces) whose :class:`LegPlacement`
is plain, serialisable data that an upload check hands to the fit
(:func:`replace_leg` rebuilds the leg from it without searching again).

Steps (mm throughout):
1. clean-up (:mod:`app.geometry.scan.cleanup`): floor or platform, spikes, stray pieces;
2. candidate legs: each remaining piece; a whole body (longer than
   :data:`app.geometry.placement.leg_pairs.BODY_MIN_LENGTH_MM`) or two legs joined at the hips
   (two shins side by side, :func:`app.geometry.placement.leg_pairs.split_two_legs`) is cut into
   its legs;
3. each candidate is placed by :func:`app.geometry.placement.leg_axis.place_candidate`: the
   shank's axis (for a bent knee, cut free of the thigh), B, C, D along it, anterior;
4. the legs found: none - the failure of the largest candidate; copies of one leg (two
   passes of a scanner not merged, a hollowed mesh's inner wall:
   :func:`app.geometry.placement.leg_copies.one_copy_per_leg`) - the outer copy with the
   most points, warned about; one - it; several - the one named by ``side``, or
   :data:`FailureReason.SEVERAL_LEGS` listing them;
5. a single leg's side, when not given: from its foot (:mod:`app.geometry.anatomy.side`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.geometry.anatomy.other_leg import other_leg_beside, other_leg_confirmed
from app.geometry.anatomy.side import infer_side
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.placement import calf_frame as cf
from app.geometry.placement.leg_axis import CalfAxis, place_candidate
from app.geometry.placement.leg_copies import one_copy_per_leg
from app.geometry.placement.leg_pairs import split_legs
from app.geometry.placement.leg_placement import LegPlacement, PlacedLeg
from app.geometry.placement.leg_size import SHAPE_REASONS, check_leg_size, with_unit_hint
from app.geometry.scan.cleanup import CleanScan, clean_scan
from app.geometry.scan.reader import MIN_POINTS, Scan
from app.geometry.sections.cloud import MIN_CLOUD_POINTS_PER_MM

#: a given side against a foot inference at least this confident is warned about (on the
#: inference's own scale, app.geometry.anatomy.side: 0.5 is a symmetric foot, 1 a clear one)
CONTRADICTED_SIDE_CONFIDENCE = 0.9

#: a piece shorter than this cannot hold an ankle, a calf and a knee waist, mm
#: (ANSUR II: lateral malleolus to tibiale is at least ~300 mm)
MIN_LEG_LENGTH_MM = 200.0



#: the record's warning for a leg cut from the other leg it touched in the scan
TOUCHING_LEGS_WARNING = (
    "the two legs touched in the scan (feet together): they were cut apart at the plane between them, and where "
    "they touch this leg's girths are read across the contact, its skin pressed against the other leg; for a "
    "made-to-measure order, scan with the feet apart")


@dataclass(frozen=True)
class _Candidate:
    points: np.ndarray
    faces: np.ndarray | None
    up: np.ndarray | None
    piece: int
    half: int
    n_points: int = field(default=0)
    #: cut from a leg it touched (:attr:`LegCut.touching`)
    touching: bool = False


def _placement_of(axis: CalfAxis, mm_per_unit: float) -> LegPlacement:
    """The serialisable placement of a placed candidate (its side and piece filled in
    later by :func:`place_leg`)."""
    return LegPlacement(axis.rotation, axis.origin_mm, mm_per_unit, axis.anterior_cue, axis.c_mm, axis.d_mm,
                        axis.d_at_window_edge, axis.b_at_scan_edge, axis.d_at_scan_edge, half_spaces=axis.half_spaces,
                        caps=axis.caps)


def _candidates(clean: CleanScan) -> list[_Candidate]:
    """Candidate legs: every cleaned piece, bodies and joined pairs of legs cut in two."""
    out = []
    for piece, index in enumerate(clean.pieces):
        points = clean.points[index]
        faces = cf.submesh(index, clean.faces, len(clean.points))
        cuts = split_legs(points, faces, clean.spacing_p95_mm)
        if cuts is None:
            out.append(_Candidate(points, faces, None, piece, -1, len(points)))
            continue
        for half, cut in enumerate(cuts):
            out.append(_Candidate(points[cut.point_index], cf.submesh(cut.point_index, faces, len(points)),
                                  cut.up, piece, half, len(cut.point_index), cut.touching))
    return out


def _sides_of(legs: list[tuple[_Candidate, LegPlacement]]) -> list[str]:
    """Left / right of two or more legs of one person, from their shared anterior and up
    directions (right = anterior x up), the legs compared along that direction."""
    up = sum(p.rotation[2] for _, p in legs)
    anterior = sum(p.rotation[1] for _, p in legs)
    right = np.cross(anterior, up)
    along = np.array([p.origin_mm @ right for _, p in legs])
    sides = ["unknown"] * len(legs)
    order = np.argsort(along)
    sides[order[0]], sides[order[-1]] = "left", "right"
    return sides


def _scan_round_leg(clean: CleanScan, placement: LegPlacement) -> tuple[np.ndarray, float]:
    """The whole cleaned scan (its own piece's other half, pieces of their own) in the
    placed leg's calf frame, (n, 3) mm, and the occupancy cell the other-leg rules read it
    on (:mod:`app.geometry.anatomy.other_leg`): twice the scan's point spacing, as the
    two-leg split's."""
    return placement.frame.to_calf(clean.points), max(10.0, 2.0 * (clean.spacing_p95_mm or 0.0))


def _why_not_placed(failures: list[tuple[_Candidate, FitFailure]], leg: str) -> str:
    """Why the ``leg`` beside the placed one (its words: "the right leg, 343 mm to its
    right") was not placed: the refusal of the
    largest part of the scan that could not be placed (that leg; its first sentence, the
    rest is how to scan a leg, said once after), with how densely a cloud samples it -
    a cloud's far leg is often its sparse one - or that no ankle, calf and knee waist
    were found on it.  ``failures``: (part, its refusal) per part not placed."""
    if not failures:
        return f"no ankle, calf and knee waist were found on {leg}"
    part, failure = max(failures, key=lambda f: f[0].n_points)
    first = str(failure).split(". ")[0].rstrip(".")
    length = float(np.ptp(part.points, axis=0).max()) if len(part.points) else 0.0
    density = f", {part.n_points / length:.1f} per mm of its length" if length > 0 else ""
    return f"{leg} ({part.n_points} points{density}), was refused: {first}"


def _describe(placement: LegPlacement, side: str, points: int) -> str:
    return f"a {side} leg ({points} points, calf {placement.c_mm:.0f} mm above its ankle)"


def place_leg(scan: Scan, side: str | None) -> PlacedLeg:
    """Find the leg of ``scan`` (see the module docstring); raises FitFailure.

    A refusal about the leg's shape on a scan too short to be a leg names the unit that
    would make it one, and one whose calf-like bulges were all set aside, sized for no
    human calf in the unit read, the unit they would be a calf in
    (:func:`app.geometry.placement.leg_size.with_unit_hint`)."""
    try:
        return _place_leg(scan, side)
    except FitFailure as failure:
        extent = float(np.ptp(scan.points_mm, axis=0).max()) if len(scan.points_mm) else 0.0
        if not scan.is_mesh and failure.reason in SHAPE_REASONS and failure.reason is not FailureReason.TOO_SPARSE:
            # a cloud too sparse to measure fails on its shape; over its length it needs
            # twice a leg's density (a body or two legs hold two legs side by side)
            density = len(scan.points_mm) / max(extent, 1e-9)
            if density < 2 * MIN_CLOUD_POINTS_PER_MM:
                raise FitFailure(
                    FailureReason.TOO_SPARSE,
                    f"the cloud is too sparse to find the leg in: it has {density:.1f} points per mm of its length; a "
                    f"cloud needs about {MIN_CLOUD_POINTS_PER_MM:g} point per mm of each leg's height "
                    f"({2 * MIN_CLOUD_POINTS_PER_MM:g} per mm of a body's or two legs' length) to close its sections: "
                    "export the scan denser, or as a mesh") from failure
        hinted = with_unit_hint(failure, extent, scan.units, scan.units_detected)
        if hinted is failure:
            raise
        raise hinted from failure


def _place_leg(scan: Scan, side: str | None) -> PlacedLeg:
    clean = clean_scan(scan.points_mm, scan.faces)
    if len(clean.points) < MIN_POINTS:  # e.g. a mesh of zero-area triangles only
        raise FitFailure(
            FailureReason.TOO_FEW_POINTS,
            f"after removing the floor, needle triangles and stray points, {len(clean.points)} of the scan's "
            f"{len(scan.points_mm)} points are left; at least {MIN_POINTS} are needed",
        )
    warnings = []
    if clean.floor is not None:
        warnings.append(f"a floor or platform plane was removed ({clean.floor.n_removed} points)")
    if clean.n_spike_faces:
        warnings.append(f"{clean.n_spike_faces} needle triangles (spikes) were removed")
    legs: list[tuple[_Candidate, LegPlacement]] = []
    failures: list[tuple[_Candidate, FitFailure]] = []
    for candidate in _candidates(clean):
        extent = np.ptp(candidate.points, axis=0).max() if len(candidate.points) else 0.0
        if extent < MIN_LEG_LENGTH_MM and len(clean.pieces) > 1:
            continue
        try:
            legs.append((candidate, _placement_of(place_candidate(candidate.points, candidate.faces, candidate.up), scan.mm_per_unit)))
        except FitFailure as failure:
            failures.append((candidate, failure))
    if not legs:
        if failures:
            raise max(failures, key=lambda f: f[0].n_points)[1]
        raise FitFailure(FailureReason.NOT_A_LEG, "no part of the scan is long enough to be a lower leg")
    ignored = len(clean.pieces) - len({c.piece for c, _ in legs})
    if ignored > 0:
        warnings.append(f"{ignored} detached piece(s) of the scan were ignored (no ankle, calf and knee in them)")
    legs, copies = one_copy_per_leg(legs)
    warnings.extend(copies)
    found: str | None
    source: str | None
    confidence: float | None = None
    if len(legs) == 1:
        candidate, placement = legs[0]
        round_leg, pixel = _scan_round_leg(clean, placement)
        beside = other_leg_beside(round_leg, placement.d_mm, pixel)
        if beside is not None:
            # a second leg stands beside the one placed: its position tells the side, and a
            # side given against it names the leg this scan could not measure
            if side not in (None, beside.measured_side):
                raise FitFailure(
                    FailureReason.SEVERAL_LEGS,
                    f"the scan holds two legs, but only the {beside.measured_side} one could be measured: "
                    f"{_why_not_placed(failures, f'the {side} leg, {beside.offset_mm:.0f} mm to its {beside.side}')}; "
                    f"scan the whole {side} leg from below the ankle to above the knee, or pass "
                    f"side={beside.measured_side} to measure the other leg")
            found, source = beside.measured_side, ("given" if side else "body")
        else:
            guess = infer_side(placement.frame.to_calf(candidate.points), placement.anterior_cue)
            if side is not None:
                # the clinician's side is kept (a foot can mislead: a deformity, an amputated
                # toe, a bandage), but a confident foot that says otherwise is said in the
                # record's warnings - left and right swap medial and lateral in every design
                found, source = side, "given"
                contradicted = (guess.side is not None and guess.side != side
                                and (guess.confidence or 0.0) >= CONTRADICTED_SIDE_CONFIDENCE)
                confirming = other_leg_confirmed(round_leg, placement.d_mm, pixel) if contradicted else None
                if confirming is not None and confirming.measured_side == guess.side:
                    # ... unless a second leg, seen too briefly to tell the side alone (the
                    # upper thigh of a leg cut off above its knee), stands where the foot
                    # says: two cues against the side given name the leg this scan cannot
                    # measure (benchmarks/other_leg.py 16 11: 3 legs cut 640-650 mm above
                    # the sole were measured under the cut leg's side)
                    raise FitFailure(
                        FailureReason.SEVERAL_LEGS,
                        f"the scan holds two legs, but only the {guess.side} one could be measured: its foot looks "
                        f"like a {guess.side} foot (confidence {guess.confidence:.2f}) and the other leg's thigh, "
                        f"above its knee, lies to its {confirming.side}; "
                        f"{_why_not_placed(failures, f'the {side} leg')}; scan the whole {side} leg from below the "
                        f"ankle to above the knee, or pass side={guess.side} to measure the other leg")
                if contradicted:
                    warnings.append(
                        f"the side was given as {side}, but the foot in the scan looks like a {guess.side} foot "
                        f"(confidence {guess.confidence:.2f}): the record is a {side} leg as asked; if the side is "
                        "wrong, medial and lateral are swapped in every design - check the scan and upload it again "
                        "with the right side")
            else:
                found, source, confidence = guess.side, ("foot" if guess.side else None), guess.confidence
                if guess.side is None and guess.reason:
                    warnings.append(f"left or right could not be told: {guess.reason}")
    else:
        sides = _sides_of(legs)
        if side is None or side not in sides:
            listed = "; ".join(_describe(p, s, c.n_points) for (c, p), s in zip(legs, sides))
            hint = "pass side=left or side=right" if side is None else f"no {side} leg could be told apart"
            raise FitFailure(FailureReason.SEVERAL_LEGS, f"the scan holds {len(legs)} legs: {listed}; {hint}")
        pick = sides.index(side)
        candidate, placement = legs[pick]
        found, source = side, "body"
    if candidate.touching:
        warnings.append(TOUCHING_LEGS_WARNING)
    if placement.half_spaces:
        warnings.append("the knee is bent: the shank was cut free of the thigh at the plane bisecting "
                        "the knee angle, and measured only where that cut leaves its sections whole")
    for cap in placement.caps:
        end = "top" if float(np.asarray(cap.normal) @ placement.rotation[2]) > 0 else "bottom"
        warnings.append(f"the scan is closed at its {end} end by a surface that is not skin (a cap a mesh tool "
                        f"adds to make a scan watertight, reaching {cap.depth_mm:.0f} mm past the cut): it was left "
                        "out and the leg measured as cut there; export the scan without closing its holes")
    if placement.b_at_scan_edge:
        # the edge passes as B when the girth levels off into it; a leg cut 27 mm above its
        # ankle waist, whose cut's partial sections level off, read cB 8.2 mm high and cB1
        # 3.4 (benchmarks/other_leg.py 24 3, case 14): the warning says how it may be wrong
        warnings.append("the scan starts at the ankle minimum B: B is taken at the scan's edge, where the girth "
                        "levels off; if the ankle narrows further below the scan, cB and cB1 read high (by up to 8 "
                        "mm on a leg cut 27 mm above its ankle waist) - include the heel in the next scan for a "
                        "surer ankle")
    if placement.d_at_window_edge and not placement.d_at_scan_edge:
        warnings.append("the knee waist D has no distinct minimum below the knee: D is the top of its search window "
                        f"({placement.d_mm - placement.c_mm:.0f} mm above the calf maximum), and its height and girth "
                        "are less certain than the other landmarks'")
    if placement.d_at_scan_edge:
        # the edge passes as D when the girth levels off into it (waists.minimum_reached_at_edge):
        # of the 5 generated scans that end there (benchmarks/robustness.py 220 7) 4 read cD
        # within 1.3 mm, one cut 52 mm below its knee waist 9 mm wide - the edge's girth can
        # only be the waist's or more
        # ... and where the waist is flat, the edge's girth is the waist's and the waist may
        # lie below it: a sparse lower leg cut 20 mm above its waist read lD 22 mm high at
        # cD 1.2 mm off (benchmarks/chart_accuracy.py 8 9, leg 6)
        warnings.append("the scan ends at the knee waist D: D is taken at the scan's edge, so the knee waist may be "
                        "thinner than cD and higher than lD (where the leg still narrows past the edge) or, where it "
                        "is flat, up to 2-3 cm lower than lD at about cD's girth; scan 3-4 cm further above the knee "
                        "for a surer D")
    placement = LegPlacement(**{**placement.__dict__, "side": found, "side_source": source,
                                "side_confidence": confidence, "piece": candidate.piece,
                                "half": candidate.half, "warnings": tuple(warnings),
                                "cleanup": clean.replay})
    leg = PlacedLeg(*placement.cut_out(candidate.points, candidate.faces), placement)
    # a leg in inches reads as one in cm: the girth at C tells (app.geometry.placement.leg_size)
    check_leg_size(placement.frame.to_calf(leg.points), placement.c_mm, scan.units, scan.units_detected)
    return leg


def replace_leg(scan: Scan, placement: LegPlacement) -> PlacedLeg:
    """The leg of a placement found earlier on the same scan, without searching again:
    the clean-up is repeated from the floor planes and voxel size it found, and the same
    piece and leg are cut out."""
    clean = clean_scan(scan.points_mm, scan.faces, placement.cleanup)
    if placement.piece >= len(clean.pieces):
        raise FitFailure(FailureReason.INVALID_OPTION, "the stored placement does not match this scan")
    index = clean.pieces[placement.piece]
    points, faces = clean.points[index], cf.submesh(index, clean.faces, len(clean.points))
    if placement.half >= 0:
        cuts = split_legs(points, faces, clean.spacing_p95_mm)
        if cuts is None:
            raise FitFailure(FailureReason.INVALID_OPTION, "the stored placement does not match this scan")
        # the half holding the placed leg's ankle centre B: the halves come in the order
        # of the split's 2-means labels, which a change of the split between the check
        # and the fit (a release in between) may turn round
        origin = np.asarray(placement.origin_mm, dtype=np.float64)
        cut = min(cuts, key=lambda c: float(np.linalg.norm(points[c.point_index] - origin, axis=1).min(initial=np.inf)))
        points, faces = points[cut.point_index], cf.submesh(cut.point_index, faces, len(points))
    return PlacedLeg(*placement.cut_out(points, faces), placement)
