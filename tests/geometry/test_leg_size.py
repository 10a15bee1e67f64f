"""The unit check after placement (app.geometry.leg_size): a leg in inches is not fitted
as one in centimetres."""

from __future__ import annotations

import pytest

from app.geometry.errors import FitFailure
from app.geometry.fit import check_scan
from app.geometry.leg_size import MAX_CALF_GIRTH_MM, MIN_CALF_GIRTH_MM, likeliest_unit
from app.geometry.scan_io import load_scan
from benchmarks.hostile_inputs import leg_in_inches


@pytest.mark.parametrize("units", [None, "cm"])
def test_a_leg_in_inches_is_refused_naming_inches(units):
    with pytest.raises(FitFailure) as caught:
        check_scan(load_scan(leg_in_inches(), file_type="stl", units=units))
    assert caught.value.reason.value == "implausible_size"
    assert "units=in" in caught.value.detail and "inches" in caught.value.detail


def test_the_same_leg_with_units_in_is_placed_as_the_mm_leg():
    placement = check_scan(load_scan(leg_in_inches(), file_type="stl", units="in"))
    assert 150 < placement["c_mm"] < 260


def test_no_adult_calf_in_another_unit_reads_as_plausible():
    """ANSUR II's calves (266-523 mm) in inches read as cm, in cm read as mm or in mm read
    as cm all fall outside the band; every one in the band is named back to its unit."""
    for girth in (266.0, 385.0, 523.0):
        for wrong in (girth / 2.54, girth / 10, girth * 10):
            assert not MIN_CALF_GIRTH_MM <= wrong <= MAX_CALF_GIRTH_MM
        assert likeliest_unit(girth / 2.54, "cm") == ("in", pytest.approx(girth))
        assert likeliest_unit(girth / 10, "mm")[0] == "cm"
