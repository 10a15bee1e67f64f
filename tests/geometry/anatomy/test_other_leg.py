"""The other leg beside the measured one (app.geometry.anatomy.other_leg) on tubes in
the calf frame (mm, B at the origin, x the subject's right)."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.anatomy.other_leg import other_leg_beside
from tests.phantoms import tube_mesh


def _tube(centre_x: float, radius: float, bottom: float, top: float) -> np.ndarray:
    """The vertices (n, 3) of a round tube standing at x = ``centre_x``."""
    heights = np.arange(bottom, top, 2.0)
    return tube_mesh(heights, np.full(len(heights), radius), np.full(len(heights), radius)).vertices + [centre_x, 0, 0]


MEASURED = _tube(0.0, 55.0, -60.0, 700.0)  # the measured leg, B to mid-thigh
D_MM = 380.0


@pytest.mark.parametrize(("centre_x", "other_side"), [(-200.0, "left"), (200.0, "right")])
@pytest.mark.parametrize("bottom", [150.0, 300.0, 450.0])
def test_a_second_leg_cut_short_beside_the_measured_one_tells_its_side(centre_x, other_side, bottom):
    """A second leg of the same girth, its lower part missing (cut ``bottom`` mm above
    B), tells which side of the measured leg it stands on."""
    found = other_leg_beside(np.vstack([MEASURED, _tube(centre_x, 55.0, bottom, 700.0)]), D_MM)
    assert found is not None and found.side == other_side
    assert found.measured_side != other_side
    assert abs(found.offset_mm - abs(centre_x)) < 10.0


def test_a_single_leg_a_hand_beside_it_or_a_scrap_of_leg_tell_nothing():
    """One leg alone, a forearm-thin limb beside its knee (a fifth of its section) and a
    leg-sized piece only 40 mm tall (two slabs) are not a second leg; neither are two
    legs whose sections touch at every height (one blob per slab)."""
    assert other_leg_beside(MEASURED, D_MM) is None
    assert other_leg_beside(np.vstack([MEASURED, _tube(150.0, 22.0, 300.0, 700.0)]), D_MM) is None
    assert other_leg_beside(np.vstack([MEASURED, _tube(-200.0, 55.0, 560.0, 600.0)]), D_MM) is None
    assert other_leg_beside(np.vstack([MEASURED, _tube(-112.0, 55.0, 0.0, 700.0)]), D_MM) is None


def test_legs_on_both_sides_tell_nothing():
    """A leg-sized blob on each side at the same heights is no single other leg."""
    both = np.vstack([MEASURED, _tube(-200.0, 55.0, 100.0, 700.0), _tube(200.0, 55.0, 100.0, 700.0)])
    assert other_leg_beside(both, D_MM) is None
