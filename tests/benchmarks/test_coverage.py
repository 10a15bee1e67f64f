"""A leg the scanner did not see all round (benchmarks/coverage.py), made at test time."""

from __future__ import annotations

from itertools import islice

import pytest

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.fit.pipeline import FitOptions, check_scan
from app.geometry.scan.reader import load_scan
from benchmarks.coverage import leg_scans

pytestmark = pytest.mark.slow


def test_a_strip_at_the_limit_that_hides_the_knee_waist_is_refused_for_the_strip():
    """benchmarks/coverage.py 20 31, leg 10: a cloud missing a 107-degree strip along the
    whole leg, its arcs read at the partial-view limit (100 degrees) at three quarters of
    its heights.  Read across the strip the knee waist was lost and the leg was refused as
    ``no_knee`` ("the knee waist is not in the scan"), which it is; it is refused for the
    strip, with the shape reading's words."""
    _, _, scans = next(islice(leg_scans(11, 31), 10, None))
    data, file_type, what = scans["strip_cloud"]
    assert what == "strip 107 deg"
    scan = load_scan(data, file_type=file_type, units="mm")
    with pytest.raises(FitFailure) as caught:
        check_scan(scan, FitOptions())
    assert caught.value.reason is FailureReason.PARTIAL_VIEW, caught.value.detail
    assert caught.value.detail.startswith("the leg's shape could not be read (no_knee:")
    assert "on the same side of the leg holds no skin" in caught.value.detail
