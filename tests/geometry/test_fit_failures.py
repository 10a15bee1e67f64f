"""Scans that are not usable legs fail with their own specific reason, never a traceback."""

import numpy as np
import pytest
import trimesh

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.fit.pipeline import FitOptions, fit_scan
from app.geometry.scan.reader import load_scan
from tests.conftest import REAL


def _fit(mesh, **options):
    return fit_scan(load_scan(mesh.export(file_type="stl"), file_type="stl"), FitOptions(**options))


def _crop(mesh, keep):
    faces = mesh.faces[keep(mesh.triangles_center)]
    return trimesh.Trimesh(mesh.vertices, faces)


@pytest.fixture(scope="module")
def leg():
    return trimesh.load(REAL / "bodyparts3d_right_leg.stl")


def _reason(mesh, **options):
    with pytest.raises(FitFailure) as info:
        _fit(mesh, **options)
    assert info.value.detail
    return info.value.reason


def test_a_cube_is_not_a_leg():
    assert _reason(trimesh.creation.box(extents=(300, 300, 300)).subdivide_to_size(10)) == FailureReason.NOT_A_LEG


def test_a_sphere_is_not_a_leg():
    assert _reason(trimesh.creation.icosphere(subdivisions=5, radius=150)) == FailureReason.NOT_A_LEG


def test_a_straight_tube_has_no_calf():
    tube = trimesh.creation.cylinder(radius=50, height=400, sections=128).subdivide_to_size(8)
    assert _reason(tube) == FailureReason.NOT_A_LEG


def test_a_scan_cut_above_the_ankle_has_no_ankle(leg):
    # the ankle minimum of this leg lies at scan z ~ 108 mm: keep the lower leg from
    # z = 170 mm (mid-shin) to z = 480 mm (above the knee)
    cut = _crop(leg, lambda c: (c[:, 2] > 170) & (c[:, 2] < 480))
    with pytest.raises(FitFailure) as info:
        _fit(cut)
    assert info.value.reason == FailureReason.NO_ANKLE
    assert "the ankle (B" in info.value.detail and "Re-scan from below the ankle bones" in info.value.detail


def test_a_scan_cut_below_the_knee_has_no_knee(leg):
    # calf maximum at scan z ~ 300 mm, minimum below the knee at ~ 364 mm
    cut = _crop(leg, lambda c: c[:, 2] < 335)
    with pytest.raises(FitFailure) as info:
        _fit(cut)
    assert info.value.reason == FailureReason.NO_KNEE
    assert "knee" in info.value.detail


def test_invalid_options_are_refused(leg):
    assert _reason(leg, points_per_layer=2) == FailureReason.INVALID_OPTION
    assert _reason(leg, side="middle") == FailureReason.INVALID_OPTION
    assert _reason(leg, mode="magic") == FailureReason.INVALID_OPTION


def _number_before(detail: str, words: str) -> float:
    """The number (mm) just before ``words`` in a refusal's detail."""
    import re

    found = re.search(r"(\d+) mm " + re.escape(words), detail)
    assert found, detail
    return float(found.group(1))


@pytest.mark.parametrize("bottom", [150.0, 170.0])
def test_a_no_ankle_detail_measures_the_scan_it_describes(leg, bottom):
    """The refusal's "reaches N mm below the calf maximum" is the scan's: the whole
    leg's calf maximum C, mapped back into the file (its frame's matrix), lies N mm
    above the cut scan's start ``bottom``, to within 15 mm (C on a cut profile is found
    again within its crown, along a slightly different axis)."""
    whole = _fit(leg)
    c_scan = whole.frame.matrix() @ np.array([0.0, 0.0, whole.landmarks.C.height_mm, 1.0])
    cut = _crop(leg, lambda c: (c[:, 2] > bottom) & (c[:, 2] < 480))
    with pytest.raises(FitFailure) as info:
        _fit(cut)
    assert info.value.reason == FailureReason.NO_ANKLE
    reach = _number_before(info.value.detail, "below the calf maximum")
    assert abs(reach - (c_scan[2] - bottom)) < 15.0, (reach, c_scan[2] - bottom)


def test_a_scan_that_ends_inside_the_calf_says_how_far_it_rises(leg):
    """Cut at z = 260 mm, below this leg's calf maximum (~300 mm): the girth rises from
    the ankle (~108 mm) to the top edge, and the refusal says it ends inside the calf
    with that rise measured on the scan (within 15 mm)."""
    cut = _crop(leg, lambda c: c[:, 2] < 260)
    with pytest.raises(FitFailure) as info:
        _fit(cut)
    assert info.value.reason == FailureReason.NO_KNEE
    if "ends inside the calf" in info.value.detail:
        rise = _number_before(info.value.detail, "up to the scan's top edge")
        assert abs(rise - (260.0 - 108.0)) < 15.0, info.value.detail
    else:  # refused by the knee rule of a calf candidate: its reach is the scan's too
        reach = _number_before(info.value.detail, "above the calf maximum")
        assert reach < 60.0, info.value.detail
