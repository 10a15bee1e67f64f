"""The refusals' words (app.geometry.anatomy.landmark_refusals): a landmark lost on a
profile cut to a window along the calf's own axis is not said as the scan's end."""

from __future__ import annotations

from app.geometry.anatomy.landmark_refusals import ends_inside_calf, failure_stage, lost_inside_window, no_ankle, no_calf, no_knee
from app.geometry.errors import FailureReason

WINDOW = (-70.0, 330.0)  # B - 70 mm to D + 70 mm along the calf's axis


def test_a_knee_lost_below_the_windows_top_is_not_said_as_the_scans_end():
    """The scan goes on 300 mm past the window (a whole leg): "the scan reaches 150 mm
    above the calf maximum" would be false.  Same reason and class, so the refusal ranks
    as it did among the leg's readings."""
    for failure in (no_knee(150.0), ends_inside_calf(120.0, 300.0, 380.0, at_top=True)):
        said = lost_inside_window(failure, WINDOW, (-400.0, 630.0), 6.4)
        assert said is not failure and type(said) is type(failure) and said.reason is FailureReason.NO_KNEE
        assert failure_stage(said) == failure_stage(failure)
        assert "scan reaches" not in said.detail and "scan's top edge" not in said.detail
        assert "knee waist" in said.detail and "not found again along the calf's own axis (6 degrees" in said.detail


def test_an_ankle_lost_above_the_windows_bottom_is_said_so_too():
    said = lost_inside_window(no_ankle(200.0), WINDOW, (-300.0, 335.0), 3.0)
    assert said.reason is FailureReason.NO_ANKLE and "the ankle (B" in said.detail and "scan reaches" not in said.detail


def test_a_window_the_scan_ends_inside_keeps_the_refusal_as_it_was():
    """The scan itself ends within the window at the end the refusal names (or the
    refusal is about something else): the scan's end is the truth, said as before."""
    knee, ankle, calf = no_knee(150.0), no_ankle(200.0), no_calf("no calf bulge")
    assert lost_inside_window(knee, WINDOW, (-400.0, 320.0), 6.0) is knee
    assert lost_inside_window(ankle, WINDOW, (-60.0, 630.0), 6.0) is ankle
    assert lost_inside_window(calf, WINDOW, (-400.0, 630.0), 6.0) is calf
