"""The tape's loops on the foot's planes (app.geometry.anatomy.foot_loops): the bound of
what a loop's chords may miss, on curves whose arcs are known."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull

from app.geometry.anatomy.foot_loops import chord_excess


def test_a_loops_chords_are_bounded_by_its_neighbouring_edges():
    """chord_excess on circles whose arcs are known: 36 points of a 40 mm circle (0.32 mm
    short of it) are bounded, loosely - each edge's turn is counted in full at both of
    its ends, about 12 times what a smooth arc's chords miss; a 90-degree gap (6.5 mm
    short) is bounded by the neighbouring edges continued, 5.4 times; an arch's flat bottom missing on the floor (the tape
    runs along the floor) is bounded by the floor, and without it by nothing (as deep
    as the floor is put)."""
    radius = 40.0
    angles = np.linspace(0.0, 2 * np.pi, 36, endpoint=False)
    circle = radius * np.column_stack([np.cos(angles), np.sin(angles)])
    no_floor = (np.array([0.0, 1.0]), -1e9)
    missed = 2 * np.pi * radius - ConvexHull(circle).area
    assert missed <= chord_excess(circle, *no_floor) <= 13.0 * missed
    open_circle = circle[angles < 1.5 * np.pi + 1e-9]  # 270 degrees of it
    missed = 2 * np.pi * radius - ConvexHull(open_circle).area
    assert missed > 6.0 and missed <= chord_excess(open_circle, *no_floor) <= 6.0 * missed
    # an arch 60 mm wide: a half circle on upright sides down to 1 mm above the floor
    # (y = 0), the floor itself gone: its bottom chord is 2 mm short of the tape along
    # the floor; the bound adds 1.2 mm at each side, where the arch's last edge,
    # continued, leaves room for a bulge beside the upright
    top = np.linspace(0.0, np.pi, 37)
    side = np.linspace(1.0, 30.0, 30)
    arch = np.vstack([np.column_stack([np.zeros(30), side]), np.column_stack([np.full(30, 60.0), side]),
                      np.column_stack([30.0 + 30.0 * np.cos(top), 30.0 + 30.0 * np.sin(top)])])
    assert 2.0 <= chord_excess(arch, np.array([0.0, 1.0]), 0.0) <= 5.0
    assert chord_excess(arch, *no_floor) > 1e9  # as deep as the floor is put
