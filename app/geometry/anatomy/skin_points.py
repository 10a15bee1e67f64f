"""Which of a scan's points are skin: a cloud's stray points (a scanner's ghosts off the
skin, a floor's strays, a streak leaving the skin) are not, and a measure that reads a
scan's extreme point - the sole's lowest, the foot's ends, the thigh's rearmost - reads
it on skin points only.

A scanner's ghosts 5-40 mm off the skin and a floor's stray points under the heel were
taken for its lowest point (the corpus's cloud_outliers read every length 5-12 mm long),
and ghosts behind the thigh for its back (G 10 mm high).  Skin is a surface sampled about
evenly: sampled at random with median nearest-neighbour spacing m, a disc of radius r
round a point of it holds about ln 2 (r / m)^2 other points (Poisson sampling: a point's
nearest neighbour lies beyond m with probability 1/2), 11 at r = STRAY_RADIUS_SPACINGS m,
more on a scanner's regular grid; a ghost off the skin holds none, a floor's stray points
under the heel one or two.  A cloud's point with fewer than STRAY_NEIGHBOURS (a third of
the skin's) is no skin, nor is a point of a scanner's streak, a line of points leaving the
skin (its nearest points spread along one line:
app.geometry.sections.cloud_edges.STREAK_SHARE).

m is local, the median over the SPACING_SAMPLE points nearest the decision (the heel's
lowest, for the sole; the foot's ends): a scanner's spacing changes over a foot (a
tessellation's vertices: 0.4 mm apart on the heel's back, 1.2 mm on the sole), and a
spacing taken over the whole foot took the sole's points for strays (lB 1.9 mm short)
and, on a body's 6,500 vertices, most of a forefoot's.  Only the points that decide are
tested (the heel's back, the lowest points, the foot's ends and its heel's corner, the
thigh's rearmost).  A mesh's vertices are joined skin (the clean-up removed its stray
pieces: app.geometry.scan.cleanup).

Arrays: points (n, 3) mm.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from app.geometry.sections.cloud_edges import STREAK_NEIGHBOURS, on_a_streak

#: a cloud's stray point: fewer than STRAY_NEIGHBOURS within STRAY_RADIUS_SPACINGS median
#: spacings (module docstring)
STRAY_RADIUS_SPACINGS = 4.0
STRAY_NEIGHBOURS = 4
#: a scanner's streak is a line of points, the skin a surface: a streak's points near the
#: skin passed as skin where the streak's own scatter or a stray beside it spread their
#: 8 nearest off one line past the streak share (a streak running 30 mm on along the floor
#: from the toes among a floor's stray points held the foot's end: foot length 30 mm long
#: and cA 5 mm short, unwarned; benchmarks/chart_accuracy.py 8 19, leg 3, cloud_outliers).
#: A point is on a line too when LINE_SHARE of its LINE_NEIGHBOURS nearest lie within one
#: spacing of a line through it (:func:`on_a_line`): a streak's own points do, strays
#: beside it do not (a share of them, not a spread, so a few strays cannot hide the line).
#: The skin's 24 nearest cover a disc about 6 spacings in radius (Poisson: ln 2 (r/m)^2 =
#: 24), of which a strip 2 spacings wide through its middle holds about 4 / (pi 5.9) = 22%:
#: on a tube sampled at random (tests/geometry/anatomy/test_skin_points.py) the best of the
#: lines tried held 33% of them in the median, 54% at p99, 0.6 or more on 0.07% of its
#: points; the points of a streak with 12 strays beside it, 67-100% (median 81%)
LINE_NEIGHBOURS = 24
LINE_SHARE = 0.6
LINE_CANDIDATES = 8
#: the skin's spacing round the points tested is the median over this many of them
SPACING_SAMPLE = 2000
#: the lowest points are tested this many at a time, lowest first
STRAY_BATCH = 256
#: :meth:`Skin.of_each`: a point's STRAY_NEIGHBOURS-th nearest distance over the median of
#: its neighbours' own.  On skin, above the knee (BodyParts3D's 27k-face leg's 5k vertices,
#: two generated legs' clouds of 37-43k points, one sparse on one side, a body mesh's 1.3k
#: vertices), it reached 2.2-2.5 at p99.9 and 1.5-3.8 at most (the most on BodyParts3D's
#: crease and the sparse side's edge); ghosts 5-40 mm off those skins (0.7% of the points)
#: reach 2-5 in the median, about their distance off the skin over 2.4 spacings.  At 1.66
#: (the sole's rule, 4 spacings) BodyParts3D's vertices lost 4 of its crease's and put G 8
#: mm low; at 4, above every skin point measured, the ghosts more than about 10 spacings
#: off the skin are strays (the one that held the back of a thigh's band: 5)
STRAY_REACH_RATIO = 4.0
#: :meth:`Skin.of_each`: a point's STRAY_NEIGHBOURS-th nearest distance over the median of
#: the points tested.  A side scanned 4 times sparser has its spacing twice the dense
#: side's, the median lying between, and a tessellation's vertices spread 0.4-20 mm
#: apart: on the backs of thighs it reached 4.0 at most on the cloud sparse on one side,
#: 4.9 on BodyParts3D's vertices, 2.2 on an even cloud, 1.5 on a body mesh's vertices;
#: twice the most measured
STRAY_ISOLATION = 8.0


def on_a_line(points: np.ndarray, index: np.ndarray, nearest: np.ndarray, spacing_mm: float) -> np.ndarray:
    """(k,) bool: the points ``index`` (k,) of ``points`` (n, 3) mm through which a line
    holds LINE_SHARE of their ``nearest`` (k, m) within ``spacing_mm`` of it (LINE_SHARE's
    docstring: a streak's, not the skin's).  The lines tried run through the point and
    each of its LINE_CANDIDATES nearest after the first LINE_CANDIDATES (as RANSAC tries
    lines through pairs: strays beside a streak tilt a fitted axis off it, a line through
    two of its points is the streak's; through a point a few spacings along it, which its
    scatter turns by a degree, where the nearest, closer than the scatter, turn it by tens)."""
    centre = points[index][:, None, :]  # (k, 1, 3)
    around = points[nearest] - centre  # (k, m, 3)
    direction = around[:, LINE_CANDIDATES:2 * LINE_CANDIDATES]  # (k, c, 3): towards each candidate
    direction = direction / np.maximum(np.linalg.norm(direction, axis=2, keepdims=True), 1e-12)
    along = np.einsum("kmi,kci->kcm", around, direction)  # (k, c, m)
    off_sq = np.einsum("kmi,kmi->km", around, around)[:, None, :] - along**2
    return ((off_sq <= spacing_mm**2).mean(axis=2) >= LINE_SHARE).any(axis=1)


class Skin:
    """Which of a scan's points are skin (module docstring), asked of the few points that
    decide a measure: every point of a mesh; a cloud's with STRAY_NEIGHBOURS within
    STRAY_RADIUS_SPACINGS median spacings of the points round them and not on a streak
    (app.geometry.sections.cloud_edges.on_a_streak).  ``points`` (n, 3) mm; ``is_mesh``: they are a mesh's vertices;
    ``tree``: a cloud's k-d tree over ``points`` when the caller has built one."""

    def __init__(self, points: np.ndarray, is_mesh: bool, tree: cKDTree | None = None):
        self.points = points
        if is_mesh or len(points) <= STRAY_NEIGHBOURS + 1:
            self.tree = None
        else:
            self.tree = tree if tree is not None else cKDTree(points)

    def of(self, index: np.ndarray, near: np.ndarray | None = None) -> np.ndarray:
        """(k,) bool for the points ``index`` (k,), the spacing the median over the points
        ``near`` (indices; ``index`` itself when None)."""
        if self.tree is None or not len(index):
            return np.ones(len(index), dtype=bool)
        near = index if near is None else near
        sample = self.points[near[:: max(len(near) // SPACING_SAMPLE, 1)]]
        spacing = float(np.median(self.tree.query(sample, k=2)[0][:, 1]))
        radius = STRAY_RADIUS_SPACINGS * spacing
        dense = self.tree.query_ball_point(self.points[index], radius, return_length=True) - 1 >= STRAY_NEIGHBOURS
        # a streak: its nearest points spread along one line, where a surface's spread in two
        _, nearest = self.tree.query(self.points[index], k=min(max(STREAK_NEIGHBOURS, LINE_NEIGHBOURS) + 1, len(self.points)))
        streak = on_a_streak(self.points, nearest)
        if nearest.shape[1] > LINE_NEIGHBOURS:  # (a cloud of a few dozen points has no lines to tell)
            streak |= on_a_line(self.points, index, nearest[:, 1:LINE_NEIGHBOURS + 1], spacing)
        return dense & ~streak

    def of_each(self, index: np.ndarray) -> np.ndarray:
        """(k,) bool for the points ``index`` (k,) spread over a scan whose spacing changes
        among them (the whole back of a thigh; a scanner that saw one side at a slant, the
        corpus's cloud_uneven, samples it 4 times sparser, and a tessellation's vertices
        crowd and thin out along a crease).  A point is a stray when its
        STRAY_NEIGHBOURS-th nearest point lies

        - more than :data:`STRAY_REACH_RATIO` times as far as the median of the same
          distance of its STREAK_NEIGHBOURS nearest points: the skin round it, for a ghost
          near the skin the skin it floats off; or
        - more than :data:`STRAY_ISOLATION` times as far as the median over all the
          points tested: a ghost far off the skin has other ghosts nearest (700 ghosts
          round a leg lie 20-40 mm apart) and reads as their "skin";

        or when it is on a streak.  One median spacing over them all, as the sole's test
        reads it (4 spacings), took 455 of a sparse side's 37k points for strays and the
        fold for noise."""
        if self.tree is None or not len(index):
            return np.ones(len(index), dtype=bool)
        distance, nearest = self.tree.query(self.points[index], k=STREAK_NEIGHBOURS + 1)
        reach = distance[:, STRAY_NEIGHBOURS]
        around = self.tree.query(self.points[nearest[:, 1:].ravel()], k=STRAY_NEIGHBOURS + 1)[0][:, -1]
        near_skin = reach <= STRAY_REACH_RATIO * np.median(around.reshape(len(index), -1), axis=1)
        in_skin = reach <= STRAY_ISOLATION * float(np.median(reach))
        return near_skin & in_skin & ~on_a_streak(self.points, nearest)

    def first(self, index: np.ndarray, key: np.ndarray, skip: int = 0) -> int | None:
        """The (``skip`` + 1)-th skin point of ``index`` (k,) in the order of ``key`` (k,)
        rising (its index into the points), None when there are not so many
        (:meth:`leading`)."""
        found = self.leading(index, key, skip + 1)
        return int(found[skip]) if len(found) > skip else None

    def leading(self, index: np.ndarray, key: np.ndarray, count: int) -> np.ndarray:
        """The first ``count`` skin points of ``index`` (k,) in the order of ``key`` (k,)
        rising (indices into the points; fewer when there are not so many); the spacing is
        that of the SPACING_SAMPLE points first in that order (where the decision is)."""
        if not len(index) or count < 1:
            return np.zeros(0, dtype=np.int64)
        if self.tree is None:  # a mesh: the first in order, found without sorting them all
            part = np.argpartition(key, min(count, len(key)) - 1)[:count]
            return index[part[np.argsort(key[part], kind="stable")]]
        leading = np.argpartition(key, min(SPACING_SAMPLE, len(key) - 1))[:SPACING_SAMPLE]
        order = index[leading[np.argsort(key[leading], kind="stable")]]  # the spacing is theirs
        found: list[np.ndarray] = []
        for start in range(0, len(order), STRAY_BATCH):  # one batch unless hundreds of strays lie first
            batch = order[start:start + STRAY_BATCH]
            found.append(batch[self.of(batch, order)])
            if sum(map(len, found)) >= count:
                return np.concatenate(found)[:count]
        if len(index) > SPACING_SAMPLE:  # more strays than the first SPACING_SAMPLE points: all, in order
            rest = index[np.argsort(key, kind="stable")[SPACING_SAMPLE:]]
            found.append(rest[self.of(rest, order)])
        return np.concatenate(found)[:count]
