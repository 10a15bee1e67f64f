"""Something against the thigh (app.geometry.anatomy.thigh_contact) read on the sections
of a thigh of revolution: a hand over G at the leg's outer side is found, a shelf of skin
at the scan's ragged top is not, a garment's hem is, all round (F and G with a hand or a
garment on the thigh: test_thigh.py)."""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.anatomy.side import outer_side_angle
from app.geometry.anatomy.thigh_contact import thigh_contact
from app.geometry.sections import tape_sections
from tests.geometry.anatomy.test_thigh import FOLD, D, _hand_held, _in_loose_garment, _leg, _radius

G = D + FOLD  # the gluteal fold, calf frame mm
CUT = 40.0  # the scan's top, mm over G


def _straight_thigh() -> np.ndarray:
    """The test leg of revolution (test_thigh._leg) with its centre kept on the axis (no
    buttock), cut CUT mm over G: (n, 3) calf-frame mm."""
    return _leg(top=FOLD + CUT, centre_y=lambda z: 0.0 * z)


def _with_shelf(leg: np.ndarray, width_mm: float) -> np.ndarray:
    """``leg`` with a shelf of skin over its cut at the outer side (+x): a strip
    ``width_mm`` wide across, running out 40 mm from the skin and rising 0.4 mm per mm
    (where the hip's skin turns outwards, a scan's ragged top holds such a piece: each
    plane through it cuts a patch ~10 mm across, 100 mm or more from the thigh's axis)."""
    skin_x = float(_radius(np.array([FOLD + CUT]))[0])
    rng = np.random.default_rng(1)
    x = rng.uniform(skin_x - 5.0, skin_x + 35.0, 3000)
    y = rng.uniform(-width_mm / 2, width_mm / 2, 3000)
    return np.vstack([leg, np.column_stack([x, y, G + CUT + 2.0 + 0.4 * (x - skin_x + 5.0)])])


def _contact(scan: np.ndarray):
    """thigh_contact on ``scan``'s sections every 5 mm from D to 60 mm over G (as
    app.geometry.anatomy.thigh reads them), for a right leg (its outer side +x)."""
    planes = np.arange(D, min(G + 60.0, scan[:, 2].max() - 2.0), 5.0)
    sections = tape_sections(scan, None, planes)
    return thigh_contact(sections, np.arange(len(planes)), D + 100.0, G, outer_side_angle("right"))


@pytest.mark.parametrize("width_mm", [8.0, 12.0, 20.0])
def test_a_shelf_of_skin_at_the_scans_ragged_top_is_no_contact(width_mm):
    """The planes through the shelf cut a patch whose own outline is closed, 100-130 mm
    from the thigh's centroid: compared with the thigh's whole outline below it, its
    "move" was 99 mm (chart_accuracy 8 5 leg 3's clouds: 45 mm, F and G left unmeasured
    for a contact that was not there).  Outlines whose centroids lie further apart than
    MAX_CENTROID_SHIFT_MM are not compared."""
    assert _contact(_straight_thigh()) is None
    assert _contact(_with_shelf(_straight_thigh(), width_mm)) is None


def test_a_hand_over_g_at_the_outer_side_is_still_found_under_a_ragged_top():
    """A hand (30 mm thick) whose fingertips lie 15 mm over G at the leg's outer side,
    with the shelf at the top: its fingertips move the outline out by more than the rule's
    10 mm where the centroid moves by far less than MAX_CENTROID_SHIFT_MM, so it is found
    and starts at its fingertips (less the 20 mm rise it is read over)."""
    tip = G + 15.0
    leg = _with_shelf(_straight_thigh(), 12.0)
    centre_z = tip + 185.0 / 2
    held = _hand_held(leg, float(_radius(np.array([centre_z - D]))[0]), (0.0, centre_z), (120, 180))
    contact = _contact(held[held[:, 2] <= G + CUT + 20.0])
    assert contact is not None
    assert tip - 26.0 <= contact.start_mm <= tip + 5.0
    assert contact.excess_mm > 10.0


@pytest.mark.parametrize("offset_mm", [5.0, 10.0, 20.0])
def test_a_garments_hem_is_found_all_round_and_a_bare_thighs_rise_is_not(offset_mm):
    """A loose tube of fabric from 120 mm under G up: the whole outline moves out by the
    offset and the thigh's own rise at once, so the arc rule (read beyond the median)
    sees nothing, and the hem rule (the median itself over ALL_ROUND_MOVE_MM) finds it,
    from the hem less the 20 mm rise it is read over.  The bare thigh, its radius rising
    0.2 mm per mm (4 mm over 20 mm, as steep as the generated legs' steepest), is not."""
    hem = G - 120.0
    contact = _contact(_in_loose_garment(_straight_thigh(), hem, offset_mm))
    assert contact is not None and contact.all_round
    assert hem - 21.0 <= contact.start_mm <= hem + 1.0
    assert contact.excess_mm >= offset_mm
    assert "the thigh is covered" in contact.reason()
    assert _contact(_straight_thigh()) is None
