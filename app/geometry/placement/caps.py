"""Caps: the surface a mesh tool adds to close a scan's cut ends, found and left out.

A scanner sees a leg from outside and leaves its ends open where the scan was cut (above
the ankle, above the knee, at the thigh).  A tool that makes a mesh "watertight" (for 3D
printing, or because its format or the next tool wants a solid) closes each open end: a
flat fill across the cut (hole filling by triangulating the boundary loop) or a smooth
dome (a Poisson reconstruction, a "make solid").  That surface is no skin, and read as
the leg it is measured as one: a cap over the top of a thigh is a bulge whose girth falls
to nothing - the thigh taken for a calf ("a foot, not a calf") - and a cap over an ankle
cut narrows the leg into an ankle that is not there (benchmarks/exported_meshes.py: 5 of
20 generated scans exported capped were refused, every one cut from the ankle to the thigh).

The rule (:func:`closing_caps`), on a mesh, along the leg's first axis
(:mod:`app.geometry.placement.first_axis`), at each end of the leg:

1. The end is closed only when a surface facing along the leg's axis crosses it there
   (:func:`closed_across`, on two of three lines along the axis through the middles of
   the end's rings of vertices): a cut end is open across the leg, whatever else the export did to
   it (a wall joined to its rim, its faces given twice, holes beside it), and where the
   leg bends off the axis the line leaves through skin facing across it.
2. Read the girth every :data:`SPACING_MM` over the last :data:`SEARCH_MM` of that end
   (36 rays, as the coarse profile of
   :func:`app.geometry.placement.straight_reading.profile_along`).  A leg's girth
   changes slowly along it between the ankle and the top of the thigh: at most about 2.6
   mm of girth per mm of height on the generated legs' profiles away from the foot (the
   steepest is just above the ankle bones).  A surface closing the leg takes its girth
   down: across a cut oblique by an angle a, a flat fill drops it at pi / tan(a) mm per mm
   (11.7 at 15 degrees); a dome h high over a radius r drops it at 2 pi r tan(phi) / h at
   the angle phi up its profile (an ellipse's quarter).  Read from the leg towards the
   end, the first fall steeper than :data:`CLOSING_SLOPE` past which no section is wider
   and the last - within :data:`CLOSED_TO_END_MM` of the end: a closing reaches it - is
   under :data:`CLOSED_SHARE` of the girth before it is the cap's; the
   cap goes on inwards while the girth still falls towards the end faster than
   :data:`TAPER_SLOPE`, for at most as long again (the rim of a dome leans in gently).
3. There is the rim.  A closing whose leg inside the rim is elongated as a foot's
   sections are (:data:`FOOT_SPAN_MM` of it, median over
   :data:`app.geometry.anatomy.calf_candidates.MAX_CALF_ELONGATION`) is a sole: the foot
   closes the leg, skin all round.  Else the cap is left out (:func:`leave_out_caps`): a
   flat fill - the faces past the rim facing along the axis, in one plane - as the faces
   in its plane, so that the skin an oblique cut leaves past the rim stays as the scanner
   saw it; any other cap as everything past the plane across the axis halfway between the
   rim and the cap's first section.

What this does not find: a cap that is a piece of its own (not sharing the cut's
vertices: the clean-up's pieces drop it, as any stray piece), a cap across a cut that
is not an end of the leg's axis (a foot cut at the midfoot, whose fill stands upright:
it closes the foot's end, not the leg's), and a closure less steep than
:data:`CLOSING_SLOPE` (a dome more than ~1.6 times as high as its radius), which is read
as the leg.  What it leaves: a dome over an oblique cut is cut off across the axis at
the cut's nearest point, with the skin the cut leaves beyond it (a scan that starts at
its ankle minimum then loses the sections that showed the girth levelling off there).
Units: mm; frame: the scan's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.anatomy.calf_candidates import MAX_CALF_ELONGATION
from app.geometry.scan.mesh_parts import used_vertices
from app.geometry.sections import slice_polar

#: how much of each end is searched for a cap, mm (a dome 0.6 of a thigh's 90 mm radius
#: high is 54 mm long)
SEARCH_MM = 120.0
#: the spacing of the sections read there, mm
SPACING_MM = 2.0
#: rays per section (the coarse profile's: a 36-gon's circumference is 0.13% short)
RAYS = 36
#: a girth rising towards the leg faster than this, mm of girth per mm of height, is a
#: closing surface, not a leg's: 1.5 times the steepest of the generated legs' profiles
#: away from the foot (2.6, above the ankle bones); a surface leaning 33 degrees or more
#: in from the axis all round (4 / 2 pi = tan 32.5 deg)
CLOSING_SLOPE = 4.0
#: ... and its rim is where the girth stops falling towards the end faster than this, mm
#: per mm: a dome's rim leans in gently (on a dome 0.6 of its radius high the girth falls
#: 1 mm per mm where it is 0.45% short of the cut's), while a leg levelling off into its
#: ankle minimum falls by 0.04-0.3 mm per mm (the generated legs cut at the ankle) and a
#: thigh widens towards its top
TAPER_SLOPE = 1.0
#: a leg closes past a steep fall when no section further out is wider and its outermost
#: section is under this share of the girth before the fall: a cap takes the girth down
#: (a fill nearly across the axis is crossed by the last plane alone, 74% of the girth on
#: a generated ankle), while past a noisy mesh's jump of CLOSING_SLOPE between two
#: sections (its girth's noise is +-3 mm) the skin runs on to the end at the leg's girth
CLOSED_SHARE = 0.9
#: a face the leg's axis crosses closes the leg when its normal lies within this of the
#: axis, degrees: a fill across a cut oblique by up to 60 degrees, a dome off its crown
#: (the line through the end's vertices misses the crown where an oblique cut's skin pulls
#: their middle aside: 47 degrees on a generated thigh's dome), a sole; not the skin a
#: bending leg's axis leaves through (within 20 degrees of across the axis)
ACROSS_DEG = 60.0
#: the lines a closing is looked for on pass through the middles of the rings of vertices
#: this far from the end, mm
ENDS_RINGS_MM = (20.0, 40.0, 60.0)
#: a closing reaches the end: its outermost section lies within this of the end, mm (a
#: cap's crown, an oblique fill's tip are small closed sections; a cut end seen obliquely
#: - the thigh of a seated leg along the leg's diagonal - has no section for 28 mm)
CLOSED_TO_END_MM = 6.0
#: a closing is a sole when the sections over this much of the leg inside its rim are
#: elongated as a foot's (median over MAX_CALF_ELONGATION), mm: a foot is that long over
#: its heel and instep (50+ mm), while a fill over a cut that is not planar leaves mixed,
#: elongated sections only next to the rim (1.46 falling to 1.2 over 10 mm at a generated
#: thigh's top)
FOOT_SPAN_MM = 30.0
#: the faces past a rim facing along the leg's axis (within this, degrees) are a fill when
#: they lie in one plane (to FLAT_MM rms) and cover at least FILL_AREA_SHARE of the rim's
#: section: a flat fill over a planar cut, whose plane is the cut's
FILL_LEAN_DEG = 30.0
FLAT_MM = 0.5
FILL_AREA_SHARE = 0.5

@dataclass(frozen=True)
class Cap:
    """A cap found at one end of a leg: the leg is kept where ``(p - point) . normal <= 0``
    (``point`` (3,) on the axis at the rim, ``normal`` (3,) unit along the axis towards
    the end, scan mm); ``depth_mm`` how far the cap reached past the rim along the axis."""

    point: np.ndarray
    normal: np.ndarray
    depth_mm: float
    #: a flat fill: ``point`` and ``normal`` are its plane's, and only the fill (the faces
    #: lying in the plane, facing along it) and what lies beyond it are left out - the
    #: skin an oblique cut leaves past the rim is kept, as the scanner saw it
    flat: bool = False


def leave_out_caps(points: np.ndarray, faces: np.ndarray | None,
                   caps: tuple[Cap, ...]) -> tuple[np.ndarray, np.ndarray | None]:
    """The leg without its ``caps``: points (n, 3) scan mm and faces (f, 3) of what is
    left (the vertices no face uses any more dropped).  A cap beyond a rim's plane: every
    point past the plane; a flat fill: every point more than :data:`FLAT_MM` past its
    plane and the faces within FLAT_MM of it facing along its normal (within
    :data:`FILL_LEAN_DEG`)."""
    if not caps or faces is None:
        return points, faces
    keep = np.ones(len(points), dtype=bool)
    fill = np.zeros(len(faces), dtype=bool)
    corners = points[faces] if any(cap.flat for cap in caps) else None
    for cap in caps:
        beyond = (points - cap.point) @ cap.normal
        keep &= beyond <= (FLAT_MM if cap.flat else 0.0)
        if corners is not None and cap.flat:
            fill |= _facing_along(corners, cap.normal, FILL_LEAN_DEG)[1] & np.all(np.abs(beyond[faces]) <= FLAT_MM, axis=1)
    kept_faces = faces[~fill & keep[faces].all(axis=1)]
    used, kept_faces = used_vertices(kept_faces, len(points))
    return points[used], kept_faces


def _facing_along(corners: np.ndarray, direction: np.ndarray, within_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(f,) twice the area of each triangle ``corners`` (f, 3, 3), and (f,) bool whether its
    normal lies within ``within_deg`` of the unit ``direction`` (3,) either way round (a
    triangle of no area has no normal: False)."""
    facing = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])  # (f, 3), 2 x area
    area2 = np.linalg.norm(facing, axis=1)
    return area2, (area2 > 0) & (np.abs(facing @ direction) >= np.cos(np.radians(within_deg)) * area2)


def closed_across(local: np.ndarray, faces: np.ndarray, middles: np.ndarray, from_mm: float,
                  towards: float) -> np.ndarray:
    """(L,) bool: whether a surface closes the leg across its axis between the height
    ``from_mm`` and the end ``towards`` (+1: the high end, -1: the low end), on each of the
    lines along z through ``middles`` (L, 2): whether the line meets a face there that
    faces along the axis (its normal within :data:`ACROSS_DEG` of it).  local (n, 3) mm in
    the axis's frame (z along it), faces (f, 3).  An end the scanner cut is open across
    the leg - however the mesh was exported: its rim doubled into a wall, its faces given
    twice, holes beside it - and a cap closes it (as a sole closes a foot); where the leg
    bends off the axis near its end (an ankle below a thigh's axis), a line leaves through
    the skin, which faces across it, and that is no closing."""
    xy = [local[faces[:, k], :2] for k in range(3)]  # the corners seen along z, (f, 2) each
    low = np.minimum(np.minimum(xy[0], xy[1]), xy[2])  # the faces' boxes seen along z
    high = np.maximum(np.maximum(xy[0], xy[1]), xy[2])
    out = np.zeros(len(middles), dtype=bool)
    for line, middle in enumerate(np.asarray(middles, dtype=np.float64).reshape(-1, 2)):
        inside = (low[:, 0] <= middle[0]) & (middle[0] <= high[:, 0]) & (low[:, 1] <= middle[1]) & (middle[1] <= high[:, 1])
        near = local[faces[inside]]  # (m, 3, 3): the faces whose box the line passes
        a = near[:, 0, :2]
        along_b, along_c, to_p = near[:, 1, :2] - a, near[:, 2, :2] - a, middle[None, :] - a
        det = along_b[:, 0] * along_c[:, 1] - along_c[:, 0] * along_b[:, 1]  # 2 x the face's area seen along z
        flat = det == 0  # a face seen edge-on along the axis
        safe = np.where(flat, 1.0, det)
        u = (to_p[:, 0] * along_c[:, 1] - along_c[:, 0] * to_p[:, 1]) / safe
        v = (along_b[:, 0] * to_p[:, 1] - to_p[:, 0] * along_b[:, 1]) / safe
        hit = ~flat & (u >= 0) & (v >= 0) & (u + v <= 1)
        met = near[hit]
        z = met[:, 0, 2] + u[hit] * (met[:, 1, 2] - met[:, 0, 2]) + v[hit] * (met[:, 2, 2] - met[:, 0, 2])
        facing = _facing_along(met, np.array([0.0, 0.0, 1.0]), ACROSS_DEG)[1]
        out[line] = bool(np.any(facing & (towards * (z - from_mm) > 0)))
    return out


def _closing_rim(girth: np.ndarray, elongation: np.ndarray) -> tuple[int, int] | None:
    """The indices of the rim of a cap and of the first section of the cap beyond it, on
    sections read from an end inwards (girth (k,) mm, NaN where a section holds nothing;
    elongation (k,)), or None when the leg does not close there or a foot closes it
    (module docstring, steps 2 and 3).

    Read from the inside out (from the leg, which is surely skin, towards the end): the
    leg runs on while its girth falls towards the end no faster than CLOSING_SLOPE; a
    steeper fall is the closing when the leg closes beyond it - no section further out is
    wider than the rim, and the outermost is under CLOSED_SHARE of the rim's girth (a
    noisy mesh's girth jumps by more than CLOSING_SLOPE between two sections, but its
    skin runs on to the end at the leg's girth).  The rim is stepped back over the
    sections before it that fall faster than TAPER_SLOPE, at most as far as the closing reaches beyond it.  A
    section's own shape between the rim and the end, partial or not, is not asked: a fill
    over a cut that is not planar (round the crotch) leaves sections of fill and skin
    mixed there, elongated and partly seen; the foot is told on the leg inside the rim
    (FOOT_SPAN_MM)."""
    seen = np.flatnonzero(np.isfinite(girth) & (girth > 0))[::-1]  # from the inside out
    if len(seen) < 3 or seen[-1] * SPACING_MM > CLOSED_TO_END_MM:
        return None  # the sections stop short of the end: it is open there (a cut), not closed
    g = girth[seen]
    falling = (g[:-1] - g[1:]) / (np.abs(np.diff(seen)) * SPACING_MM)  # towards the end, per mm
    beyond_max = np.maximum.accumulate(g[::-1])[::-1]  # the widest section from each one out
    for rim in np.flatnonzero(falling > CLOSING_SLOPE):
        if beyond_max[rim + 1] <= g[rim] and g[-1] <= CLOSED_SHARE * g[rim]:
            break
    else:
        return None
    reach = seen[rim]  # sections from the rim to the end
    back = int(rim)
    while back > 0 and falling[back - 1] > TAPER_SLOPE and seen[back - 1] - seen[rim] <= reach:
        back -= 1
    at = int(seen[back])
    inside = elongation[at : at + int(FOOT_SPAN_MM / SPACING_MM) + 1]
    inside = inside[np.isfinite(inside)]
    if not inside.size or np.median(inside) > MAX_CALF_ELONGATION:
        return None
    return at, int(seen[back + 1])


def closing_caps(points: np.ndarray, faces: np.ndarray | None, basis: np.ndarray) -> tuple[Cap, ...]:
    """The caps at the ends of one leg along ``axis`` (module docstring): points (n, 3)
    scan mm, faces (f, 3) (a cloud has none: ()); ``basis`` (3, 3) rows x, y, z with z
    the leg's first axis."""
    if faces is None or not len(faces):
        return ()
    centre = points.mean(axis=0)  # the rays of a section are cast from the axis through it
    local = (points - centre) @ basis.T
    z = local[:, 2]
    used = np.zeros(len(points), dtype=bool)
    used[faces.ravel()] = True
    z_used = z[used]
    low, high = float(z_used.min()), float(z_used.max())
    if high - low < 4 * SEARCH_MM:  # too short to be a leg: the caller refuses it
        return ()
    corner_z = [z[faces[:, k]] for k in range(3)]
    face_top = np.maximum(np.maximum(corner_z[0], corner_z[1]), corner_z[2])
    face_bottom = np.minimum(np.minimum(corner_z[0], corner_z[1]), corner_z[2])
    caps = []
    for towards in (-1.0, 1.0):
        end = high if towards > 0 else low
        inward = end - towards * (SPACING_MM / 2 + SPACING_MM * np.arange(int(SEARCH_MM / SPACING_MM)))
        heights = np.sort(inward)
        start = float(inward[-1])  # the plane furthest in
        near = faces[face_top >= start] if towards > 0 else faces[face_bottom <= start]  # the faces reaching into it
        # lines along the axis through the middles of the rings of vertices ENDS_RINGS_MM
        # from the end: the leg's centre near its end, where it bends off the axis (a
        # cap's crown, an open cut's hole).  A cap closes the whole section: most of the
        # lines meet it; an oblique cut's ring is partial and its middle off the centre,
        # where one line may meet what lies at the skin's edge (the rim joining a wall to
        # the skin, 3 mm wide) - so three are tried and two must meet a closing
        middles = [local[ring, :2].mean(axis=0) for ring in
                   (used & (np.abs(towards * (end - z) - depth) <= SPACING_MM) for depth in ENDS_RINGS_MM) if ring.any()]
        if closed_across(local, near, np.array(middles).reshape(-1, 2), start, towards).sum() < 2:
            continue  # open across the leg: the scanner's cut
        sections = slice_polar(local, near, heights, RAYS, recentre=False)
        girth, elongation = sections.circumferences(), sections.elongations()
        order = np.argsort(towards * -heights)  # from the end inwards
        closing = _closing_rim(girth[order], elongation[order])
        if closing is None:
            continue
        rim, beyond = closing
        # the cut halfway between the rim, the leg's last section, and the cap's first
        rim_height = float(heights[order][rim] + heights[order][beyond]) / 2
        rim_centre = sections.centroids_mm[order][rim]
        xy = rim_centre if np.isfinite(rim_centre).all() else np.zeros(2)
        point = centre + basis.T @ np.array([xy[0], xy[1], rim_height])
        depth = float(towards * (end - rim_height))
        fill = _flat_fill(points, near, towards * (z - rim_height) > 0, towards * basis[2],
                          float(girth[order][rim]))
        caps.append(Cap(point, towards * basis[2], depth) if fill is None else Cap(*fill, depth, flat=True))
    return tuple(caps)


def _flat_fill(points: np.ndarray, faces: np.ndarray, past_rim: np.ndarray, outwards: np.ndarray,
               rim_girth_mm: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The plane (point (3,), unit normal (3,) towards the end) of a flat fill past a
    rim, or None when the cap there is no flat fill (a dome).  ``past_rim`` (n,) bool the
    points past the rim's plane; ``outwards`` (3,) the axis towards the end."""
    corners = points[faces]
    area2, along = _facing_along(corners, outwards, FILL_LEAN_DEG)
    area = area2 / 2
    candidate = along & past_rim[faces].all(axis=1)
    rim_area = rim_girth_mm**2 / (4 * np.pi)  # a circle of the rim's girth
    if area[candidate].sum() < FILL_AREA_SHARE * rim_area:
        return None
    weights = area[candidate]
    middle = (corners[candidate].mean(axis=1) * weights[:, None]).sum(axis=0) / weights.sum()
    spread = corners[candidate].reshape(-1, 3) - middle
    normal = np.linalg.svd(spread, full_matrices=False)[2][2]
    off = spread @ normal
    if np.sqrt(np.mean(off**2)) > FLAT_MM:
        return None
    return middle, (normal if normal @ outwards > 0 else -normal)
