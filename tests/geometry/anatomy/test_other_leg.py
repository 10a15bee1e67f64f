"""The other leg beside the measured one (app.geometry.anatomy.other_leg) on tubes in
the calf frame (mm, B at the origin, x the subject's right)."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.anatomy.other_leg import other_leg_beside, other_leg_confirmed
from tests.phantoms import tube_mesh


def _tube(centre_x: float, radius: float, bottom: float, top: float, centre_y: float = 0.0) -> np.ndarray:
    """The vertices (n, 3) of a round tube standing at x = ``centre_x``, y = ``centre_y``."""
    heights = np.arange(bottom, top, 2.0)
    return tube_mesh(heights, np.full(len(heights), radius), np.full(len(heights), radius)).vertices + [centre_x, centre_y, 0]


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


@pytest.mark.parametrize(("centre_x", "other_side"), [(-200.0, "left"), (200.0, "right")])
def test_a_thigh_seen_in_two_slabs_confirms_a_side_but_does_not_tell_it(centre_x, other_side):
    """The upper thigh of a leg cut off above its knee, 40 mm of it in the band: too
    little to tell the side alone, enough to confirm another cue's."""
    scan = np.vstack([MEASURED, _tube(centre_x, 55.0, 560.0, 600.0)])
    assert other_leg_beside(scan, D_MM) is None
    found = other_leg_confirmed(scan, D_MM)
    assert found is not None and found.side == other_side and found.slabs == 2


@pytest.mark.parametrize(("centre_x", "other_side"), [(-100.0, "left"), (100.0, "right")])
def test_a_leg_merged_with_the_body_above_its_thigh_confirms_the_other_side(centre_x, other_side):
    """Above the crotch the measured leg's section joins the other's (one blob, the
    body's midline medial to the leg): the blob's centre moves towards the other leg."""
    leg = _tube(0.0, 55.0, -60.0, 560.0)
    pelvis = _tube(centre_x, 150.0, 560.0, 700.0)  # both thighs and the hips, one section
    scan = np.vstack([leg, pelvis])
    assert other_leg_beside(scan, D_MM) is None
    found = other_leg_confirmed(scan, D_MM)
    assert found is not None and found.side == other_side and found.slabs >= 5


def test_a_single_leg_growing_into_its_buttock_or_a_ragged_top_confirms_nothing():
    """A single leg whose section grows backwards at its top (a buttock: y, not x), or
    whose top is a ragged edge of scraps beside it, holds no second leg."""
    heights = np.arange(-60.0, 760.0, 2.0)
    grows = np.clip((heights - 560.0) / 200.0, 0.0, 1.0)  # 0 below the gluteal fold, 1 at the top
    radius = 55.0 + 35.0 * grows
    buttock = tube_mesh(heights, radius, radius).vertices
    buttock[:, 1] -= 30.0 * np.clip((buttock[:, 2] - 560.0) / 200.0, 0.0, 1.0)  # its centre moves back
    assert other_leg_confirmed(buttock, D_MM) is None
    rng = np.random.default_rng(5)
    scraps = np.c_[rng.uniform(-250.0, 250.0, (40, 2)), rng.uniform(700.0, 705.0, 40)]  # one slab of specks at the top
    assert other_leg_confirmed(np.vstack([MEASURED, scraps]), D_MM) is None
