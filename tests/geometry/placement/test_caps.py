"""Caps a mesh tool closes a scan's cut ends with (app.geometry.placement.caps): found on
a closed end only, left out as the scanner's cut, a foot's sole kept - on an obliquely cut
tube and on BodyParts3D's leg exported watertight as benchmarks/corpus/exports.py does."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from app.geometry.fit.pipeline import check_scan, fit_scan
from app.geometry.placement import calf_frame as cf
from app.geometry.placement.caps import closed_across, closing_caps, leave_out_caps
from app.geometry.placement.leg_placement import LegPlacement
from app.geometry.placement.place import replace_leg
from app.geometry.scan.reader import load_scan
from benchmarks.corpus import exports
from tests.conftest import REAL, fitted

#: the oblique cut's tilt from across the tube, degrees
CUT_TILT_DEG = 20.0


def _merged(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """``mesh`` with coincident vertices merged (as a watertight export shares them)."""
    merged = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False)
    merged.merge_vertices()
    return merged


@pytest.fixture(scope="module")
def oblique_tube() -> trimesh.Trimesh:
    """An open tube of radius 45 mm along z (a leg's straight stand-in), from z = -350 to
    a top end cut at CUT_TILT_DEG across the axis through (0, 0, 290): mm, 72 columns of
    110 rows, its two ends open (planar loops)."""
    around, rows = 72, 110
    theta = 2 * np.pi * np.arange(around) / around
    x, y = 45.0 * np.cos(theta), 45.0 * np.sin(theta)
    top = 290.0 - np.tan(np.radians(CUT_TILT_DEG)) * x  # the plane with normal (sin, 0, cos)
    share = np.linspace(0.0, 1.0, rows)[:, None]
    z = -350.0 + share * (top[None, :] + 350.0)  # (rows, around)
    vertices = np.column_stack([np.broadcast_to(x, z.shape).ravel(), np.broadcast_to(y, z.shape).ravel(), z.ravel()])
    row, col = np.meshgrid(np.arange(rows - 1), np.arange(around), indexing="ij")
    a, b = row * around + col, row * around + (col + 1) % around
    faces = np.vstack([np.column_stack([a.ravel(), b.ravel(), (b + around).ravel()]),
                       np.column_stack([a.ravel(), (b + around).ravel(), (a + around).ravel()])])
    return trimesh.Trimesh(vertices, faces, process=False)


def _tube_basis(mesh: trimesh.Trimesh) -> np.ndarray:
    return cf.perpendicular_basis(np.array([0.0, 0.0, 1.0]))


@pytest.mark.parametrize("style", list(exports.CAP_HEIGHTS))
def test_a_capped_end_is_closed_across_the_axis_and_an_exported_open_end_is_not(oblique_tube, style):
    """The line along the axis meets a cap (flat or domed); it passes through an open cut
    whatever else the export did: a wall joined to the rim, every face given twice."""
    basis = _tube_basis(oblique_tube)
    centre = oblique_tube.vertices.mean(axis=0)

    def closed(mesh: trimesh.Trimesh, towards: float) -> bool:
        local = (np.asarray(mesh.vertices) - centre) @ basis.T
        return bool(closed_across(local, np.asarray(mesh.faces), np.zeros((1, 2)), 0.0, towards)[0])

    capped = _merged(exports.capped(oblique_tube, style))
    assert closed(capped, 1.0) and closed(capped, -1.0)
    for export in (oblique_tube, exports.hollowed(oblique_tube, 3.0, rims=True), exports.double_sided(oblique_tube)):
        assert not closed(export, 1.0) and not closed(export, -1.0)


def test_a_flat_fill_over_an_oblique_cut_is_left_out_and_the_skin_past_its_rim_kept(oblique_tube):
    """The fill of the oblique end is found in the cut's plane (the cut's own normal to
    0.5 degrees) and left out, and the tube is the open tube there again, face for face:
    the skin the oblique cut leaves past the rim's plane stays.  The fill of the square
    end, across the axis, is crossed by no section - it changes no reading - and stays."""
    capped = _merged(exports.capped(oblique_tube, "flat"))
    points, faces = np.asarray(capped.vertices), np.asarray(capped.faces)
    caps = closing_caps(points, faces, _tube_basis(oblique_tube))
    assert len(caps) == 1 and caps[0].flat
    cut_normal = np.array([np.sin(np.radians(CUT_TILT_DEG)), 0.0, np.cos(np.radians(CUT_TILT_DEG))])
    assert np.degrees(np.arccos(min(1.0, float(caps[0].normal @ cut_normal)))) < 0.5
    kept_points, kept_faces = leave_out_caps(points, faces, caps)
    square_fill = 72  # the fan over the square end's 72 columns
    assert len(kept_faces) == len(oblique_tube.faces) + square_fill
    assert len(kept_points) == len(oblique_tube.vertices) + 1  # the square fan's centre
    top_ring = np.abs((kept_points - [0.0, 0.0, 290.0]) @ cut_normal) < 1e-6
    assert top_ring.sum() == 72  # the cut's rim, and nothing of the fill within it


def test_an_open_tube_and_one_closed_by_a_dome_over_a_foot_like_end_are_told_apart(oblique_tube):
    """An open tube has no cap; a dome over its top is one, reaching past the rim about as
    far as the dome is high."""
    points, faces = np.asarray(oblique_tube.vertices), np.asarray(oblique_tube.faces)
    assert closing_caps(points, faces, _tube_basis(oblique_tube)) == ()
    domed = _merged(exports.capped(oblique_tube, "dome"))
    caps = closing_caps(np.asarray(domed.vertices), np.asarray(domed.faces), _tube_basis(oblique_tube))
    assert len(caps) == 2 and not any(cap.flat for cap in caps)
    height = exports.CAP_HEIGHTS["dome"] * 45.0
    # the square end's dome reaches its height past the rim, the oblique one's its height
    # and the cut's span along the axis
    square, oblique = sorted(caps, key=lambda cap: cap.normal[2])
    assert 0.8 * height <= square.depth_mm <= height + 4.0
    assert 0.8 * height <= oblique.depth_mm <= height + 2 * 45.0 * np.tan(np.radians(CUT_TILT_DEG)) + 4.0


@pytest.fixture(scope="module")
def bodyparts3d_leg() -> trimesh.Trimesh:
    return trimesh.load(REAL / "bodyparts3d_right_leg.stl")


@pytest.mark.parametrize("style", ["low_dome", "dome"])
def test_a_real_leg_exported_watertight_is_measured_as_its_scan_and_said(bodyparts3d_leg, tmp_path, style):
    """BodyParts3D's leg (open at the thigh, closed at its sole) with its thigh domed over:
    one cap, at the top - the sole is the foot's -, girths within 0.5 mm of the open scan's,
    and the record says what was left out.  The stored placement cuts the same leg out
    again (the fit's second reading of the scan)."""
    _, plain = fitted("bodyparts3d_right_leg.stl", None)
    path = tmp_path / f"capped_{style}.stl"
    exports.capped(bodyparts3d_leg, style).export(path)
    scan = load_scan(path)
    placement = check_scan(scan)
    assert len(placement.caps) == 1 and float(placement.caps[0].normal @ placement.rotation[2]) > 0.9
    said = [w for w in placement.warnings if "closed at its top end" in w]
    assert len(said) == 1 and "watertight" in said[0]
    stored = LegPlacement.from_dict(placement.to_dict())
    assert stored.caps[0].depth_mm == placement.caps[0].depth_mm and stored.caps[0].flat == placement.caps[0].flat
    again = replace_leg(scan, stored)
    fit = fit_scan(scan, placement=stored)
    assert len(again.points) < len(scan.points_mm)
    for name in ("B", "B1", "C", "D"):
        assert abs(fit.landmarks.tape_girths_mm[name] - plain.landmarks.tape_girths_mm[name]) < 0.5, name


def test_the_sole_closing_a_real_leg_is_no_cap():
    """BodyParts3D's sole closes its leg across the axis: it is the foot, not a cap."""
    scan, fit = fitted("bodyparts3d_right_leg.stl", None)
    assert fit.placement.caps == ()
    assert not any("closed at its" in w for w in fit.warnings)


@pytest.mark.slow
@pytest.mark.parametrize("style", ["flat", "dome"])
def test_a_generated_leg_cut_from_the_ankle_to_the_thigh_and_exported_watertight_fits_as_its_scan(style):
    """A generated leg scanned from the ankle to the thigh (benchmarks/corpus, ANSUR II
    subject 3105), closed at both cuts as a watertight export closes them: refused before
    caps were left out (the thigh's cap read as a bulge, "a foot, not a calf"; the
    ankle's as the leg still narrowing), it fits as its open scan - girths at B, B1, C, D
    within 0.5 mm - with a cap left out at each end: the flat fill over the planar ankle
    cut as a fill in its plane, the fan over the thigh's cut round the crotch (no plane)
    and the domes beyond their rims."""
    import dataclasses
    import io

    from benchmarks.corpus.cases import CaseSpec, build_case
    from benchmarks.corpus.evaluate import run_case
    from benchmarks.exported_meshes import as_file

    case = build_case(CaseSpec("caps-ankle-to-thigh", "ankle_to_thigh", 1016164991, 3105))
    plain = run_case(case)
    assert plain["outcome"] == "fit"
    mesh = trimesh.load(io.BytesIO(case.data), file_type=case.file_type, process=True)
    mesh.apply_transform(np.linalg.inv(case.to_scan))
    capped_case = dataclasses.replace(case, data=as_file(exports.capped(mesh, style), case.to_scan, case.file_type))
    capped = run_case(capped_case)
    assert capped["outcome"] == "fit", capped.get("detail")
    for name, error in capped["girth_error_mm"].items():
        assert abs(error - plain["girth_error_mm"][name]) < 0.5, name
    placement = check_scan(load_scan(capped_case.data, file_type=capped_case.file_type, units=capped_case.units))
    assert len(placement.caps) == 2
    ankle = max(placement.caps, key=lambda cap: -float(cap.normal @ placement.rotation[2]))
    assert float(ankle.normal @ placement.rotation[2]) < -0.9 and ankle.flat == (style == "flat")
    assert not any(cap.flat for cap in placement.caps if cap is not ankle)
    assert sum("closed at its" in w for w in placement.warnings) == 2


def test_a_refusal_of_a_leg_read_without_its_caps_says_they_were_left_out(oblique_tube):
    """A scan refused after its caps were left out is refused for the leg as cut, and
    the refusal says what was cut away (the refusal alone - no calf in a tube - would
    send the clinic looking for a fault the scan does not have); an open tube's refusal
    says nothing of caps."""
    from app.geometry.errors import FitFailure

    for mesh, said in ((_merged(exports.capped(oblique_tube, "dome")), True), (oblique_tube, False)):
        with pytest.raises(FitFailure) as caught:
            check_scan(load_scan(mesh.export(file_type="stl"), file_type="stl"))
        assert ("a cap a mesh tool adds to make a scan watertight" in caught.value.detail) is said
        assert str(caught.value) == caught.value.detail


@pytest.mark.slow
def test_an_open_leg_bending_off_its_axis_at_an_oblique_ankle_cut_has_no_cap():
    """A generated leg scanned from the ankle to the thigh (subject 2566, the scan of
    benchmarks/exported_meshes.py 4 61's leg 0): open at both cuts, its shin bending off
    the thigh's axis towards the ankle.  The line along the axis through the leg's middle
    120 mm above the ankle cut left through the skin there, the oblique cut's partial
    sections fell like a closing, and the open scan lost its ankle to a "cap" (refused
    no_ankle).  Lines through the end's own rings, and only faces facing along the axis,
    find it open."""
    from benchmarks.corpus.cases import CaseSpec, build_case

    case = build_case(CaseSpec("caps-open-ankle", "ankle_to_thigh", 1626090476, 2566))
    placement = check_scan(load_scan(case.data, file_type=case.file_type, units=case.units))
    assert placement.caps == ()
    assert not any("closed at its" in w for w in placement.warnings)
