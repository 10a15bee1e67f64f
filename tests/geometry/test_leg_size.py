"""The unit check after placement (app.geometry.placement.leg_size): a leg in inches is not fitted
as one in centimetres."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from app.geometry.errors import FitFailure
from app.geometry.fit.pipeline import FitOptions, check_scan
from app.geometry.placement.leg_size import MAX_CALF_GIRTH_MM, MIN_CALF_GIRTH_MM, likeliest_unit
from app.geometry.scan.reader import load_scan
from benchmarks.corpus.degrade import crop
from benchmarks.hostile_inputs import leg_in_inches
from tests.conftest import REAL


@pytest.mark.parametrize("units", [None, "cm"])
def test_a_leg_in_inches_is_refused_naming_inches(units):
    with pytest.raises(FitFailure) as caught:
        check_scan(load_scan(leg_in_inches(), file_type="stl", units=units))
    assert caught.value.reason.value == "implausible_size"
    assert "units=in" in caught.value.detail and "inches" in caught.value.detail


def test_the_same_leg_with_units_in_is_placed_as_the_mm_leg():
    placement = check_scan(load_scan(leg_in_inches(), file_type="stl", units="in"))
    assert 150 < placement.c_mm < 260


def test_no_adult_calf_in_another_unit_reads_as_plausible():
    """ANSUR II's calves (266-523 mm) in inches read as cm, in cm read as mm or in mm read
    as cm all fall outside the band; every one in the band is named back to its unit."""
    for girth in (266.0, 385.0, 523.0):
        for wrong in (girth / 2.54, girth / 10, girth * 10):
            assert not MIN_CALF_GIRTH_MM <= wrong <= MAX_CALF_GIRTH_MM
        assert likeliest_unit(girth / 2.54, "cm") == ("in", pytest.approx(girth))
        assert likeliest_unit(girth / 10, "mm")[0] == "cm"


# --- a refusal on a scan read in the wrong unit names the unit -------------------------




def test_a_body_in_centimetres_read_as_millimetres_is_refused_naming_centimetres(tmp_path):
    """The Visible Human female (1.7 m) written in cm reads as a 167 mm object in mm:
    its shape is refused, and the refusal says that in cm it is a body."""
    body = load_scan(REAL / "vh_female_skin.glb")
    path = tmp_path / "body_cm.ply"
    trimesh.Trimesh(body.points_mm / 10.0, body.faces, process=False).export(path)
    scan = load_scan(path)
    assert scan.units == "mm" and scan.units_detected
    with pytest.raises(FitFailure) as caught:
        check_scan(scan, FitOptions(side="left"))
    detail = caught.value.detail
    assert "units=cm" in detail and "centimetres" in detail
    length = float(np.ptp(scan.points_mm, axis=0).max())
    assert f"only {length:.0f} mm long" in detail and f"{10 * length:.0f} mm long" in detail
    placed = check_scan(load_scan(path, units="cm"), FitOptions(side="left"))
    assert placed.side == "left"


def _ankle_height(leg: trimesh.Trimesh) -> float:
    """Height (file z, mm) of the narrowest horizontal section 40-250 mm above the sole:
    the ankle minimum B of this leg, which stands along z."""
    sole = leg.vertices[:, 2].min()
    heights = np.arange(40.0, 250.0, 2.0)
    lines = trimesh.intersections.mesh_multiplane(leg, [0.0, 0.0, sole], [0.0, 0.0, 1.0], heights)[0]
    girth = [ConvexHull(segments.reshape(-1, 2)).area if len(segments) > 2 else np.inf for segments in lines]
    return float(sole + heights[int(np.argmin(girth))])


def test_a_foot_of_a_foots_size_gets_no_unit_hint(tmp_path):
    """The BodyParts3D leg cut 30 mm above its ankle: a foot, which in mm is a foot's
    size - refused as a foot (the orientation that reads its heel as a calf with no
    ankle below loses), with no hint to change the unit."""
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    foot = crop(leg, np.array([0.0, 0.0, _ankle_height(leg) + 30.0]), np.array([0.0, 0.0, -1.0]))
    path = tmp_path / "foot.stl"
    foot.export(path)
    with pytest.raises(FitFailure) as caught:
        check_scan(load_scan(path))
    assert caught.value.reason.value == "no_calf" and "a foot, not a calf" in caught.value.detail
    assert "units=" not in caught.value.detail
