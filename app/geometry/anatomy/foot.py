"""The foot's points of the order form, measured from the scan as a tape would: the foot
length, cA (the forefoot girth over the metatarsal heads) and cY (the heel-instep
diagonal), RAL-GZ 387's measuring points below B.

Frame: the calf frame (mm; z up the leg from B = 0, y anterior, x the subject's right),
``sole_mm`` the z of the sole.  Arrays: points (n, 3), faces (f, 3) or None.

- **Foot axis and length.**  The footprint (points within FOOTPRINT_MM of the sole) gives
  the foot's long axis as its first principal direction in the horizontal plane, pointed
  forward (+y); the foot length is the footprint-and-foot extent along that axis, heel to
  the tip of the longest toe (ISO 7250-1 5.3.1: foot length parallel to the foot axis),
  from the third-lowest and third-highest projection of the skin (robust to two
  stragglers the clean-up left; on a 2 mm scan this moves a tip by under 1 mm).
- **cA, the ball girth.**  ANSUR II's ball-of-foot length (heel to the first metatarsal
  head) is 0.740 +- 0.014 of the foot length (6,068 subjects, tests/data/ansur2), and the
  fifth metatarsal head lies about 0.1 of the foot length behind the first; the ball
  girth is where the forefoot is largest over them: the largest tape girth (convex hull
  of the section, :func:`app.geometry.anatomy.foot_loops.extreme_tape`) in vertical planes
  perpendicular to the foot axis from 0.62 to 0.78 of the foot length, every 2 mm.
- **cY, the heel-instep diagonal.**  The tape passes round the back of the heel and over
  the front of the ankle (ANSUR II's heel-ankle circumference; RAL-GZ 387's "Fersen-Rist-
  Umfang") and is pulled to the shortest such loop.  Its planes contain the foot's
  transverse axis and pass through the heel's posterior-inferior point (the foot point
  furthest back-and-down, at 45 degrees in the sagittal plane, on the heel's midline:
  halfway between the sides of its section 20 mm from its end, over that section's lowest
  40 mm); among those tilted 20-75
  degrees whose loop's far end lies over the ankle (0.15-0.55 of the foot length from
  the heel, not over the forefoot), cY is the shortest loop: a minimum, so the tilt's
  exact value matters to second order only (re-scans move a corner point, not a minimum).
- **A cloud's stray points** (a scanner's ghosts off the skin) are not the foot's ends
  nor its heel's corner (:class:`app.geometry.anatomy.skin_points.Skin`): taken for them they
  read a foot 15-90 mm long and cY up to 65 mm short (the corpus's cloud_outliers).
- **A side scanned sparser** (a scanner's far side) does not pull the heel's middle over:
  it is read between the sides of its section (the graph's crossings join no stray), not
  as its points' median, which also took the back of the shank and moved 7-17 mm to the
  dense side, so the corner - and cY's planes - moved up to 25 mm and cY read up to 7.6
  mm short (held-out chart_accuracy seeds 7 and 13).  The corner is a point of a cloud's
  skin graph (its largest joined part: a floor's strays, spread like a sparse skin, form
  their own) that is skin by one spacing over the points first in order - the dense
  side's, so a sparse side's corner may still read as a stray and give way to one a few
  mm over (cY up to 2 mm short).  Judged on the spacing round each point instead, a
  scanner's streak off the heel passed as skin at its root (cY +1 mm), and judged on each
  point's reach against its neighbours' so did ghosts behind the heel (cY 6-8.5 mm short).
- **A sparse loop** says what it may miss (:mod:`app.geometry.anatomy.foot_loops`): cA
  and cY carry ``uncertainty_mm`` when a cloud is too sparse round them for the loop to
  follow the skin within an order's 3 mm, with a warning to take them by tape.
- **A sparse end** likewise: the foot's ends are the third skin point from either end,
  so the foot may reach beyond each by the two skipped and, on a cloud, by the gap its
  sampling leaves before the tip: with k points within r of the end (density k / pi r^2),
  a tip of radius R (the heel's 25 mm, the big toe's 12) holds no point over a depth
  r^2 / 2kR on average, three times that in 95 cases of 100 (the gap is exponential).
  Their sum is the foot length's ``uncertainty_mm`` when more than a measuring point's
  10 mm (HIGH_CONFIDENCE_MM), at most the length itself.  The real legs read from
  4,000-8,000 of their vertices state it 11 times, each reaching the error (the 3 errors
  past 10 mm among them; benchmarks/real_samples.py); the generated re-scans never
  (benchmarks/chart_accuracy.py 8 11).
- **A foot that is not all there** is not measured: a footprint shorter than 150 mm, or
  an end that does not taper (the section 6 mm inside the toe or heel end is more than
  0.7 of the ball girth: a crop, not a toe) says why.  A cloud sampled more than 6 mm
  apart round that end (its sixth nearest point farther) reads the inset section on
  chords across the end, not on its skin (the MakeHuman leg's 1,636 unsubdivided
  vertices: a heel 173 mm round 6 mm in): the reason then says the scan may be too
  sparse there to tell a cut from a taper, and how sparse.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from app.geometry.anatomy.feature_layers import HIGH_CONFIDENCE_MM
from app.geometry.anatomy.foot_loops import (
    cloud_graph,
    extreme_tape,
    hull_girths,
    loop_sections,
    plane_sections,
    stated_shortfall,
)
from app.geometry.anatomy.skin_points import Skin
from app.geometry.anatomy.sole import HEEL_HALF_BAND_MM
from app.geometry.scan.mesh_parts import used_vertices
from app.geometry.sections import TAPE_BAND_OFFSETS_MM

#: points this close to the sole (mm) are its footprint
FOOTPRINT_MM = 25.0
#: shortest foot the rules are for (a child's foot is ~150 mm), mm
MIN_FOOT_MM = 150.0
#: the ball girth's window, as fractions of the foot length from the heel (module docstring)
BALL_WINDOW = (0.62, 0.78)
BALL_STEP_MM = 2.0
#: the ball girth is read as a tape band is: the median of the planes BALL_STEP_MM apart
#: across a tape's width round each (app.geometry.sections.TAPE_BAND_OFFSETS_MM, whose
#: planes are as far apart: +-4 mm, 5 planes).  The largest of single-plane girths is
#: biased up by their noise (a noisy cloud reads each plane 1-2 mm wide of the mesh's),
#: the largest of band medians much less; at a maximum the girth changes only to second
#: order across the band
BALL_BAND_PLANES = len(TAPE_BAND_OFFSETS_MM)
#: the heel-instep planes' tilt from the floor and its step, degrees; where their loop's
#: far end must lie (over the front of the ankle: the talus neck is 0.3-0.45 of the foot
#: length forward of the heel), fractions of the foot length from the heel
INSTEP_TILT_DEG = (20.0, 75.0)
INSTEP_STEP_DEG = 2.5
INSTEP_WINDOW = (0.15, 0.55)
#: cY is read over this many neighbouring tilts (+-2.5 degrees), as cA over its band
INSTEP_BAND_PLANES = 3
#: the heel's middle (across the foot) is halfway between the sides of its section half
#: this far from its end, over the section's lowest this much, mm
HEEL_MIDDLE_SPAN_MM = 40.0
#: an end whose section 6 mm inside is above this share of the ball girth was cut, not tapered
END_TAPER_SHARE = 0.7
END_INSET_MM = 6.0
#: the heel-instep loop rises to the front of the ankle, above B on most legs: its planes
#: see the scan below this height (mm above B; the loop tops out 20-50 mm above B)
INSTEP_TOP_MM = 80.0
INSTEP_TOP_MARGIN_MM = 10.0
#: a sparse end's sampling is read from this many nearest points round it, and the tip
#: it may miss from the radius of the heel's back (app.geometry.anatomy.sole: a round heel
#: of radius 25-30 mm, the lower taken) and of the big toe's tip (half its ~25 mm width), mm
END_DENSITY_NEIGHBOURS = 6
HEEL_RADIUS_MM = 25.0
TOE_TIP_RADIUS_MM = 12.0


@dataclass(frozen=True)
class FootPoint:
    """One measured point: ``value_mm`` (None, with the ``reason``, when not measured) and
    where on the foot, calf frame mm (the centre of the tape's loop, (3,))."""

    name: str
    value_mm: float | None
    at_mm: tuple[float, float, float] | None = None
    reason: str | None = None
    #: how much longer the skin's girth may be than the reading (mm), when a sparse loop's
    #: gaps leave more than GIRTH_TOLERANCE_MM to it (module docstring, "A sparse loop")
    uncertainty_mm: float | None = None

    def as_dict(self) -> dict:
        out = {"value_mm": self.value_mm, "at_mm": None if self.at_mm is None else list(self.at_mm), "reason": self.reason}
        if self.uncertainty_mm is not None:
            out["uncertainty_mm"] = self.uncertainty_mm
        return out


@dataclass(frozen=True)
class FootMeasures:
    foot_length: FootPoint
    ball_girth: FootPoint  # cA
    heel_instep_girth: FootPoint  # cY

    def as_dict(self) -> dict:
        return {"foot_length": self.foot_length.as_dict(), "cA": self.ball_girth.as_dict(), "cY": self.heel_instep_girth.as_dict()}

    @property
    def warnings(self) -> tuple[str, ...]:
        """A sentence for each girth a sparse loop leaves uncertain and for a foot length
        whose sparse ends do (module docstring)."""
        def short_by(point: FootPoint) -> str:  # a gap without a bound is stated as the girth itself
            if point.value_mm is not None and point.uncertainty_mm is not None and point.uncertainty_mm >= point.value_mm:
                return f"{point.name} has no bound on how short it reads"
            return f"{point.name} may read up to {point.uncertainty_mm:.0f} mm short"

        said = tuple(f"{short_by(point)}: the scan's points are too sparse round the {where} for its tape loop to "
                     f"follow the skin (the loop's chords bridge its gaps); take {point.name} by tape (RAL-GZ 387)"
                     for point, where in ((self.ball_girth, "forefoot"), (self.heel_instep_girth, "heel and instep"))
                     if point.uncertainty_mm is not None)
        if self.foot_length.uncertainty_mm is not None:
            said += (f"the foot length may read up to {self.foot_length.uncertainty_mm:.0f} mm short: the scan's points "
                     "are too sparse at the heel or the toes to show where the foot ends; take it by tape",)
        return said


def _xyz(point: np.ndarray) -> tuple[float, float, float]:
    return float(point[0]), float(point[1]), float(point[2])


def _not_measured(reason: str) -> FootMeasures:
    return FootMeasures(FootPoint("foot_length", None, reason=reason), FootPoint("cA", None, reason=reason),
                        FootPoint("cY", None, reason=reason))


def _below(points: np.ndarray, faces: np.ndarray | None, z_max: float,
           edges: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """The part of the scan below ``z_max``: a mesh keeps the faces wholly below and their
    vertices; a cloud its points below and, given its neighbour graph's ``edges`` (e, 2),
    the edges between them (renumbered; None when not given)."""
    if faces is None or not len(faces):
        keep = points[:, 2] < z_max
        if edges is None:
            return points[keep], None, None
        index = np.cumsum(keep) - 1
        return points[keep], None, index[edges[keep[edges].all(axis=1)]]
    keep = (points[faces, 2] < z_max).all(axis=1)
    used, below = used_vertices(faces[keep], len(points))
    return points[used], below, None


def foot_measures(points: np.ndarray, faces: np.ndarray | None, sole_mm: float | None,
                  no_sole_reason: str | None = None) -> FootMeasures:
    """The foot length, cA and cY of the module docstring (mm), or why not: without a
    sole, ``no_sole_reason`` (app.geometry.anatomy.sole says why a foot in the scan has
    none) or that the foot is not in the scan."""
    if sole_mm is None:
        return _not_measured(no_sole_reason or "the foot is not in the scan")
    # the part of the scan the heel-instep loop is read on, and a cloud's graph over it, once
    instep, instep_faces, _ = _below(points, faces, INSTEP_TOP_MM)
    instep_edges, instep_tree = cloud_graph(instep, instep_faces)
    # the foot: below halfway from the sole to B (the forefoot is 40-55 mm high, B 100-150
    # mm above the sole; the shank's back above the heel would cut the heel's end planes)
    below_b, below_faces, edges = _below(instep, instep_faces, 0.5 * sole_mm, instep_edges)
    footprint = below_b[below_b[:, 2] < sole_mm + FOOTPRINT_MM]
    if len(footprint) < 50:
        return _not_measured("the scan has too few points near the sole to find the foot")
    xy = footprint[:, :2] - footprint[:, :2].mean(axis=0)
    _, _, vt = np.linalg.svd(xy, full_matrices=False)
    axis2 = vt[0] if vt[0][1] >= 0 else -vt[0]
    axis = np.array([axis2[0], axis2[1], 0.0])
    across = np.cross([0.0, 0.0, 1.0], axis)
    along = below_b @ axis
    # the ends: the third skin point from either end (two stragglers the clean-up left
    # aside; a cloud's stray points are no skin, app.geometry.anatomy.skin_points.Skin)
    skin = Skin(below_b, below_faces is not None)
    every = np.arange(len(below_b))
    heel_skin, toe_skin = skin.leading(every, along, 3), skin.leading(every, -along, 3)
    if len(heel_skin) < 3 or len(toe_skin) < 3:
        return _not_measured("the scan has too few points near the sole to find the foot")
    heel_end, toe_end = int(heel_skin[2]), int(toe_skin[2])
    heel_t, toe_t = float(along[heel_end]), float(along[toe_end])
    length = float(toe_t - heel_t)
    reaches = (_end_reach(below_b, skin, heel_end), _end_reach(below_b, skin, toe_end))  # heel, toes
    length_short = (_end_shortfall(along[heel_end] - along[heel_skin[0]], reaches[0], HEEL_RADIUS_MM)
                    + _end_shortfall(along[toe_skin[0]] - along[toe_end], reaches[1], TOE_TIP_RADIUS_MM))
    if length < MIN_FOOT_MM:
        return _not_measured(f"the foot in the scan is {length:.0f} mm long, shorter than any foot "
                             f"({MIN_FOOT_MM:.0f} mm): it is cut")
    centre_x = float(np.median(below_b @ across))
    sole_point = np.array([0.0, 0.0, sole_mm]) + centre_x * across
    # cA: vertical planes across the foot axis (basis: across, up, axis)
    basis = np.array([across, [0.0, 0.0, 1.0], axis])
    origin = sole_point - (sole_point @ axis) * axis
    lo, hi = heel_t + BALL_WINDOW[0] * length, heel_t + BALL_WINDOW[1] * length
    offsets = np.arange(lo, hi + 1e-9, BALL_STEP_MM)
    window, window_sags = loop_sections(below_b, below_faces, edges, origin, basis, offsets)
    ends = hull_girths(plane_sections(below_b, below_faces, edges, origin, basis,
                       np.array([heel_t + END_INSET_MM, toe_t - END_INSET_MM])))
    foot_length = FootPoint("foot_length", length, _xyz(origin + (heel_t + toe_t) / 2 * axis),
                            uncertainty_mm=min(length_short, length) if length_short > HIGH_CONFIDENCE_MM else None)
    coarse = hull_girths(window)
    if not np.isfinite(coarse).any():
        reason = "the forefoot has no closed section over the metatarsal heads (a hole or a crop)"
        return FootMeasures(foot_length, FootPoint("cA", None, reason=reason), FootPoint("cY", None, reason=reason))
    # the floor the loops stand on (what a sparse loop may miss stays above it): the sole
    # plane, or the foot's lowest skin where lower (a standing forefoot lies within 12 mm
    # of the heel's floor, app.geometry.anatomy.sole); in the ball planes, up from the sole
    lowest = skin.first(every, below_b[:, 2])
    floor_level = min(sole_mm, float(below_b[lowest, 2])) - sole_mm if lowest is not None else 0.0
    best, ball, ball_excess = extreme_tape(window, coarse, BALL_BAND_PLANES, True,
                                           [(np.array([0.0, 1.0]), floor_level)] * len(window),
                                           window_sags)
    cut = [k for k, g in enumerate(ends) if np.isfinite(g) and g > END_TAPER_SHARE * ball]
    if cut:
        reason = (f"the {' and '.join(('heel', 'toes')[k] for k in cut)} end in a section {max(ends):.0f} mm round, "
                  "not a taper: the foot is cut")
        if max(reaches[k] for k in cut) > END_INSET_MM:
            # the inset section's crossings are chords across the end, not its skin
            reason += (f", or the scan is too sparse there to tell (its points lie {max(reaches[k] for k in cut):.0f} "
                       f"mm apart round the end, more than the {END_INSET_MM:.0f} mm inside it the taper is read at)")
        return FootMeasures(FootPoint("foot_length", None, reason=reason), FootPoint("cA", None, reason=reason),
                            FootPoint("cY", None, reason=reason))
    ball_at = origin + offsets[best] * axis
    ball_point = FootPoint("cA", ball, _xyz(ball_at + (sole_mm + 25.0 - ball_at[2]) * basis[1]),
                           uncertainty_mm=stated_shortfall(ball_excess, ball))
    return FootMeasures(foot_length, ball_point, _heel_instep(instep, instep_faces, axis, across, heel_t, length,
                                                              instep_edges, instep_tree, sole_mm + floor_level))


def _end_reach(points: np.ndarray, skin: Skin, end: int) -> float:
    """How far round the foot's ``end`` (a point's index) a cloud samples it: the distance
    to its END_DENSITY_NEIGHBOURS-th nearest point, mm (0 on a mesh, whose end is its
    extreme vertex).  ``points`` (n, 3) mm."""
    if skin.tree is None:
        return 0.0
    return float(skin.tree.query(points[end], k=END_DENSITY_NEIGHBOURS + 1)[0][-1])


def _end_shortfall(skipped_mm: float, reach_mm: float, tip_radius_mm: float) -> float:
    """How far (mm) the foot's end may lie beyond the point read as it (the third skin
    point from that end): the ``skipped_mm`` to the first, and on a cloud the gap its
    sampling may leave before the tip (module docstring, "A sparse end"):
    3 r^2 / (2 k ``tip_radius_mm``), r = ``reach_mm`` (:func:`_end_reach`, k =
    END_DENSITY_NEIGHBOURS)."""
    return float(skipped_mm) + 3.0 * reach_mm**2 / (2.0 * END_DENSITY_NEIGHBOURS * tip_radius_mm)


def _heel_instep(points: np.ndarray, faces: np.ndarray | None, axis: np.ndarray, across: np.ndarray,
                 heel_t: float, length: float, edges: np.ndarray | None, tree: cKDTree | None,
                 floor_z: float) -> FootPoint:
    """cY: the shortest loop round the heel's posterior-inferior point and over the front
    of the ankle, among the planes through that point containing the foot's transverse
    axis tilted INSTEP_TILT_DEG from the floor whose loop's far end lies over the ankle
    (INSTEP_WINDOW of the foot length from the heel: a flatter plane leaves over the
    dorsum of the forefoot and is no heel-instep loop) and below INSTEP_TOP_MM (a steeper
    one runs up the shank, out of the part of the scan it is measured on)."""
    up = np.array([0.0, 0.0, 1.0])
    heel = _heel_corner(points, faces, axis, across, heel_t, edges, tree)
    if heel is None:
        return FootPoint("cY", None, reason="the heel is not in the scan")
    tilts = np.radians(np.arange(INSTEP_TILT_DEG[0], INSTEP_TILT_DEG[1] + 1e-9, INSTEP_STEP_DEG))
    loops: list[np.ndarray] = []  # each tilt's section, empty where it is no heel-instep loop
    centres = np.zeros((len(tilts), 3))
    depths = np.zeros(len(tilts))  # each loop's chord sag (loop_sections)
    for k, tilt in enumerate(tilts):  # ~20 planes, each vectorised over the points
        in_plane = np.cos(tilt) * axis + np.sin(tilt) * up
        basis = np.array([across, in_plane, np.cross(across, in_plane)])
        sections, sags = loop_sections(points, faces, edges, heel, basis, np.array([0.0]))  # once per plane
        section = sections[0]
        loops.append(section[:0])
        if not len(section):
            continue
        end = section[int(np.argmax(section[:, 1]))]  # the loop's far end, along the rising direction
        far = heel + end[0] * basis[0] + end[1] * basis[1]
        over_ankle = heel_t + INSTEP_WINDOW[0] * length <= far @ axis <= heel_t + INSTEP_WINDOW[1] * length
        # (a loop reaching the part's cut is not closed)
        if over_ankle and far[2] <= INSTEP_TOP_MM - INSTEP_TOP_MARGIN_MM:
            loops[k], centres[k] = section, (heel + far) / 2
            depths[k] = sags[0]
    coarse = hull_girths(loops)
    if not np.isfinite(coarse).any():
        return FootPoint("cY", None, reason="no closed loop round the heel and over the front of the ankle "
                                            "(a hole or a crop)")
    # the shortest of the loops, each read as the median of it and its neighbouring tilts:
    # the least of single loops is biased down by their noise, as the ball girth's largest up
    best, girth, excess = extreme_tape(loops, coarse, INSTEP_BAND_PLANES, False,
                                       [(np.array([0.0, np.sin(tilt)]), floor_z - heel[2]) for tilt in tilts],
                                       depths)
    return FootPoint("cY", girth, _xyz(centres[best]), uncertainty_mm=stated_shortfall(excess, girth))


def _heel_corner(points: np.ndarray, faces: np.ndarray | None, axis: np.ndarray, across: np.ndarray, heel_t: float,
                 edges: np.ndarray | None, tree: cKDTree | None) -> np.ndarray | None:
    """The heel's posterior-inferior point (3,) mm, cY's pivot (module docstring), or None
    when the heel is not in the scan."""
    up = np.array([0.0, 0.0, 1.0])
    back_down = -(axis + up) / np.sqrt(2.0)
    # on the heel's midline: the planes contain the transverse axis, so where across the
    # heel the point lies does not matter, and a stray point beside the heel (a floor
    # point at the sole's level, 36 mm to its side, read cY 11 mm short) is not in the band
    side = points @ across
    # the heel's middle: halfway between the sides of its section HEEL_MIDDLE_SPAN_MM / 2
    # from its end (the mesh's plane section, a cloud's crossings of its neighbour graph,
    # which joins no stray to the skin), over the section's lowest HEEL_MIDDLE_SPAN_MM (the
    # heel proper, not the back of the shank above it), the third point from either side
    section = plane_sections(points, faces, edges, np.zeros(3), np.array([across, up, axis]),
                             np.array([heel_t + HEEL_MIDDLE_SPAN_MM / 2.0]))[0]
    heel_proper = section[section[:, 1] < section[:, 1].min() + HEEL_MIDDLE_SPAN_MM, 0] if len(section) else section
    if len(heel_proper) < 6:
        return None
    ends = np.partition(heel_proper, (2, len(heel_proper) - 3))
    middle = float(ends[2] + ends[-3]) / 2.0
    band = np.flatnonzero(np.abs(side - middle) <= HEEL_HALF_BAND_MM)
    if edges is not None and faces is None and len(edges):
        # a cloud's corner is on its skin's graph: the largest set of points its edges join
        # (a floor's strays, sampled like a sparse skin, form their own; ghosts join nothing)
        joined = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(len(points), len(points)))
        _, part = connected_components(joined, directed=False)
        band = band[part[band] == np.argmax(np.bincount(part))]
    corner = Skin(points, faces is not None, tree).first(band, -(points[band] @ back_down))
    if corner is None:
        return None
    return points[corner]
