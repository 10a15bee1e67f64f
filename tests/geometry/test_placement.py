"""Placing a leg (app.geometry.placement.place): a side given against the evidence is kept
and said."""

from __future__ import annotations

import re

import numpy as np
import pytest
import trimesh

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan
from app.geometry.scan.reader import load_scan
from benchmarks.corpus.degrade import coarsen, crop
from tests.conftest import REAL


def test_a_side_given_against_a_confident_foot_is_kept_with_a_warning():
    scan = load_scan(REAL / "bodyparts3d_right_leg.stl")
    inferred = check_scan(scan)
    assert inferred.side == "right" and inferred.side_confidence >= 0.9
    assert not any("foot in the scan looks like" in w for w in inferred.warnings)
    given = check_scan(scan, FitOptions(side="left"))
    assert given.side == "left" and given.side_source == "given"
    warning = next(w for w in given.warnings if "given as left" in w)
    assert "right foot" in warning and f"confidence {inferred.side_confidence:.2f}" in warning and "medial and lateral" in warning
    agreed = check_scan(scan, FitOptions(side="right"))
    assert not any("given as" in w for w in agreed.warnings)


# --- coarse meshes and the vertices of a body as a cloud --------------------------------




@pytest.fixture(scope="module")
def female_body():
    """The Visible Human female's skin (62k vertices, mm) and its left calf as fitted."""
    body = load_scan(REAL / "vh_female_skin.glb")
    return body, fit_scan(body, FitOptions(side="left")).landmarks


def test_a_coarse_body_mesh_places_and_fits_its_legs(female_body, tmp_path):
    """Clustered to 25 mm cells (~3.8k vertices, edges p95 ~36 mm: a registered body
    template's resolution), the body's feet are still told from its head and its left
    calf is measured within 10 mm of the full mesh's (a coarse mesh's flat facets cut
    inside the round skin)."""
    body, full = female_body
    vertices, faces = coarsen(body.points_mm, body.faces, 25.0)
    assert len(vertices) < 5000
    path = tmp_path / "coarse.ply"
    trimesh.Trimesh(vertices, faces, process=False).export(path)
    fit = fit_scan(load_scan(path), FitOptions(side="left"))
    assert fit.side == "left"
    for name in ("B", "C"):
        assert abs(fit.landmarks.tape_girths_mm[name] - full.tape_girths_mm[name]) < 10.0


def test_a_bodys_vertices_as_a_cloud_fit(female_body, tmp_path):
    """The same body clustered to 12 mm and exported as its vertices only (~15k points,
    the rings of a tessellation 3-12 mm apart): its pieces are joined and the left calf
    is measured within 3 mm of the mesh's."""
    body, full = female_body
    vertices, _ = coarsen(body.points_mm, body.faces, 12.0)
    assert 10_000 < len(vertices) < 20_000
    path = tmp_path / "vertices.ply"
    trimesh.PointCloud(vertices).export(path)
    fit = fit_scan(load_scan(path), FitOptions(side="left"))
    for name in ("B", "C"):
        assert abs(fit.landmarks.tape_girths_mm[name] - full.tape_girths_mm[name]) < 3.0
    assert any("sparse" in w for w in fit.warnings)


def test_a_sparse_bodys_leg_that_cannot_be_placed_says_why_and_how_sparse_it_is(tmp_path):
    """8,000 of the Visible Human male's vertices (a whole body, ~1,300 points a leg):
    the left leg is placed, the right is not.  Asked for the right, the refusal names the
    left as the one measured and says why the right was refused and how densely the
    cloud samples it (before, it said only that no ankle, calf and knee waist were found
    on it, as of a leg cut short)."""
    scan = load_scan(REAL / "vh_male_skin.glb")
    picked = np.random.default_rng(1).choice(len(scan.points_mm), 8_000, replace=False)
    path = tmp_path / "sparse_body.ply"
    trimesh.PointCloud(scan.points_mm[picked]).export(path)
    with pytest.raises(FitFailure) as refused:
        check_scan(load_scan(path, units="mm"), FitOptions(side="right"))
    said = str(refused.value)
    assert refused.value.reason is FailureReason.SEVERAL_LEGS and "only the left one could be measured" in said
    assert re.search(r"the right leg, \d+ mm to its right \(\d+ points, \d\.\d per mm of its length\), was refused: ", said)
    assert "side=left" in said


def _two_legs(body) -> trimesh.Trimesh:
    """The body cut 45% of its height above the soles: two legs joined at the hips (mm)."""
    up = np.array([0.0, 1.0, 0.0])  # the Visible Human files stand along +y
    sole = body.points_mm[:, 1].min()
    return crop(trimesh.Trimesh(body.points_mm, body.faces, process=False),
                np.array([0.0, sole + 0.45 * np.ptp(body.points_mm[:, 1]), 0.0]), -up)


@pytest.mark.parametrize("turned", [False, True])
def test_two_legs_cut_at_the_hips_are_read_from_their_feet(female_body, tmp_path, turned):
    """The body cut 45% of its height above the soles (feet to hips, two legs joined at
    the top) pairs up from both ends - shins at one, thighs at the other; its feet end
    is the thinner one, whichever way up the file stands, and the left calf is the body's."""
    body, full = female_body
    cut = _two_legs(body)
    if turned:  # upside down: the hips at the bottom of the file
        cut.apply_transform(trimesh.transformations.rotation_matrix(np.pi, [0.0, 0.0, 1.0]))
    path = tmp_path / "two_legs.ply"
    cut.export(path)
    fit = fit_scan(load_scan(path), FitOptions(side="left"))
    for name in ("B", "C"):
        assert abs(fit.landmarks.tape_girths_mm[name] - full.tape_girths_mm[name]) < 3.0


@pytest.mark.parametrize("cut_mm", [160.0, 400.0, 650.0])
@pytest.mark.parametrize("cut_side", ["left", "right"])
def test_two_legs_of_which_one_is_cut_short_are_never_labelled_the_short_ones_side(female_body, tmp_path, cut_side, cut_mm):
    """The body cut at the hips as above, and one leg cut ``cut_mm`` above the sole (at
    160 mm no ankle, a stump of calf, knee and thigh beside the whole leg's shin - the
    pair was not cut apart and both were refused as a partial view -, at 400 mm no calf,
    at 650 mm only its upper thigh, 100 mm below the hips cut): the other leg is the only
    one placed, and the left leg's girths are those the whole body gives.  Asked for the cut leg, the service refuses and
    names the leg it could measure (before, it measured the other leg and labelled it
    with the side asked; at 650 mm it did so until the foot and the thigh left beside it
    were read together); asked for none or for the whole one, it measures the whole one,
    its side told by where the cut leg stands or, where too little of it is left to tell
    the side alone, by the foot."""
    body, full = female_body
    vertices = body.points_mm
    sole = vertices[:, 1].min()
    hips = crop(trimesh.Trimesh(vertices, body.faces, process=False),
                np.array([0.0, sole + 0.45 * np.ptp(vertices[:, 1]), 0.0]), np.array([0.0, -1.0, 0.0]))
    ankles = {side: check_scan(body, FitOptions(side=side)).origin_mm for side in ("left", "right")}
    between = 0.5 * (ankles["left"][0] + ankles["right"][0])  # the files stand along +y, legs apart along x
    on_cut_leg = (np.sign(hips.vertices[:, 0] - between) == np.sign(ankles[cut_side][0] - between)) \
        & (hips.vertices[:, 1] < sole + cut_mm)
    hips.update_faces(~on_cut_leg[hips.faces].any(axis=1))
    hips.remove_unreferenced_vertices()
    path = tmp_path / "one_leg_cut.ply"
    hips.export(path)
    scan = load_scan(path)
    whole = "right" if cut_side == "left" else "left"
    with pytest.raises(FitFailure) as refused:
        check_scan(scan, FitOptions(side=cut_side))
    assert refused.value.reason is FailureReason.SEVERAL_LEGS
    assert f"only the {whole} one could be measured" in str(refused.value) and f"side={whole}" in str(refused.value)
    assert f"the {cut_side} leg" in str(refused.value)
    for asked in (None, whole):
        placement = check_scan(scan, FitOptions(side=asked))
        told_by = "body" if cut_mm < 600.0 else "foot"
        assert placement.side == whole and placement.side_source == (told_by if asked is None else "given")
        assert np.linalg.norm(np.asarray(placement.origin_mm) - ankles[whole]) < 15.0
    if whole == "left":  # the fixture's calf is the left one
        fit = fit_scan(scan, FitOptions(side=whole))
        for name in ("B", "C", "D"):
            assert abs(fit.landmarks.tape_girths_mm[name] - full.tape_girths_mm[name]) < 2.0


# --- one leg scanned twice ----------------------------------------------------------------


@pytest.mark.parametrize("apart_mm", [4.0, 15.0])
def test_two_unmerged_passes_of_one_leg_are_one_leg_measured_once_and_said(tmp_path, apart_mm):
    """BodyParts3D's leg and a copy of it moved ``apart_mm`` sideways in one file (two
    passes of a scanner exported unmerged, the leg moved between them): clean-up reads
    two pieces, both place as legs; they are one leg - measured on one copy, its side
    told from its foot, its girths the single leg's - and the warning says so.  Two
    legs side by side cannot overlap: the same copies 120 mm apart are two legs."""
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    alone = check_scan(load_scan(REAL / "bodyparts3d_right_leg.stl"))
    sideways = np.array([1.0, 0.0, 0.0])  # the file stands along +z
    twice = trimesh.util.concatenate([leg, leg.copy().apply_translation(apart_mm * sideways)])
    path = tmp_path / "twice.stl"
    twice.export(path)
    scan = load_scan(path)
    placement = check_scan(scan)
    assert placement.side == alone.side == "right"
    warning = next(w for w in placement.warnings if "holds this leg 2 times" in w)
    assert f"up to {apart_mm:.0f} mm apart" in warning
    fit = fit_scan(scan, placement=placement)
    single = fit_scan(load_scan(REAL / "bodyparts3d_right_leg.stl"), placement=alone)
    for name in ("B", "C", "D"):
        assert abs(fit.landmarks.tape_girths_mm[name] - single.landmarks.tape_girths_mm[name]) < 0.5

    two = trimesh.util.concatenate([leg, leg.copy().apply_translation(120.0 * sideways)])
    path = tmp_path / "two.stl"
    two.export(path)
    with pytest.raises(FitFailure) as refused:
        check_scan(load_scan(path))
    assert refused.value.reason is FailureReason.SEVERAL_LEGS


def test_a_hollowed_leg_is_measured_on_its_outer_surface(tmp_path):
    """BodyParts3D's leg with a wall 2 mm inside it, a piece of its own (a mesh hollowed
    for 3D printing): both place as the same leg with as many points, and the inner one
    read every girth 2 pi x 2 mm short (the first of equal copies was measured: the wall,
    written first here).  A scanner sees the skin from outside: the outer surface is
    measured, and the warning names the wall and its thickness."""
    leg = trimesh.load(REAL / "bodyparts3d_right_leg.stl")
    wall = trimesh.Trimesh(leg.vertices - 2.0 * leg.vertex_normals, leg.faces[:, ::-1], process=False)
    single = fit_scan(load_scan(REAL / "bodyparts3d_right_leg.stl"))
    path = tmp_path / "hollowed.stl"
    trimesh.util.concatenate([wall, leg]).export(path)
    scan = load_scan(path)
    placement = check_scan(scan)
    said = [w for w in placement.warnings if "inside the skin" in w]
    assert len(said) == 1 and "a second surface 2.0 mm inside" in said[0]
    assert not any("holds this leg" in w for w in placement.warnings)
    fit = fit_scan(scan, placement=placement)
    for name in ("B", "C", "D"):
        assert abs(fit.landmarks.tape_girths_mm[name] - single.landmarks.tape_girths_mm[name]) < 0.5


# --- swollen legs ---------------------------------------------------------------------


def _right_leg(subject_index: int, leg_seed: int):
    """A generated adult's right leg with its foot (ANSUR II subject ``subject_index``'s
    MakeHuman leg drawn from ``leg_seed``, mm, as benchmarks/swollen.py draws it) and its
    ankle and knee joints."""
    from benchmarks.corpus.makehuman import ansur_subjects, leg_submesh, sized_legs

    legs = sized_legs(ansur_subjects()[subject_index], np.random.default_rng(leg_seed), subdivisions=2)
    return leg_submesh(legs.vertices, legs.faces, -1.0), legs.joints["r-ankle"], legs.joints["r-knee"]


@pytest.fixture(scope="module")
def right_leg_of_subject_137():
    return _right_leg(137, 137)


def _swollen_scan(leg, swelling_mm: float, reach: float):
    from benchmarks.corpus.degrade import swell_lower_leg
    from benchmarks.corpus.truth import measure_truth

    mesh, ankle, knee = leg
    swollen = swell_lower_leg(mesh, ankle, knee, swelling_mm, reach)
    return load_scan(swollen.export(file_type="stl"), file_type="stl"), measure_truth(swollen, ankle, knee)


def test_a_swollen_ankle_wider_than_its_knee_waist_is_measured_foot_down(right_leg_of_subject_137):
    """Swollen 14 mm over the foot and ankle, fading to none 0.7 of the way up the shank
    (benchmarks/swollen.py): the ankle (315 mm) has grown wider than the knee waist is
    thicker than it by MIN_KNEE_RATIO, but the calf still bulges over it (C/B 1.23).  It
    was refused for a missing knee; the foot tells the ankle's end, and B, C and D are
    measured within a tape's reading of the swollen leg's own."""
    scan, truth = _swollen_scan(right_leg_of_subject_137, 14.0, 0.7)
    assert truth.girths_mm["D"] < 1.05 * truth.girths_mm["B"]
    fit = fit_scan(scan, FitOptions(side="right"))
    for name, tolerance in (("B", 2.0), ("C", 2.0), ("D", 4.0)):
        assert abs(fit.landmarks.tape_girths_mm[name] - truth.girths_mm[name]) < tolerance, name


def test_a_swollen_ankle_as_wide_as_the_calf_is_read_foot_down(right_leg_of_subject_137):
    """Swollen 25 mm, fading to none 0.9 of the way up: the ankle (385 mm) nearly as wide
    as the calf (419, C/B 1.09) and wider than the knee waist (328).  Read with the foot
    up, the knee waist passed for an ankle and the swollen ankle for a knee waist: a
    record of cB 323 and cD 390 mm, with only a warning that the foot looked like a left
    one.  A foot is at the bottom of a leg: read foot down, its ankle stands on the foot,
    the calf bulges over it by more than MIN_CALF_RATIO_ON_FOOT, and B, C and D are
    measured where they are."""
    scan, truth = _swollen_scan(right_leg_of_subject_137, 25.0, 0.9)
    assert truth.girths_mm["D"] < truth.girths_mm["B"] < truth.girths_mm["C"] < 1.2 * truth.girths_mm["B"]
    fit = fit_scan(scan, FitOptions(side="right"))
    for name, tolerance in (("B", 2.0), ("C", 2.0), ("D", 4.0)):
        assert abs(fit.landmarks.tape_girths_mm[name] - truth.girths_mm[name]) < tolerance, name
    assert not any("looks like a left foot" in w for w in fit.warnings)
    # a calf bulging less than any healthy one is said, and cD to be checked by tape
    assert any("the calf bulges only 1.09 times" in w and "cD by tape" in w for w in fit.warnings), fit.warnings


def test_a_swollen_leg_is_not_measured_on_its_thigh_as_a_bent_knees_run():
    """A leg swollen 23 mm, fading 0.87 of the way up (benchmarks/swollen.py 40 19, case
    37: subject index 2629's right leg, C/B 1.10).  Refused on its straight axis, the
    straight runs of a bent knee were tried next, and the thigh's run, cut free above the
    knee, read the knee waist as an ankle and the thigh as a calf: a record of cC 145 mm
    over the leg's.  A run whose ankle stands on no foot is not taken after the straight
    leg stood on its own; here the straight leg is measured, its calf bulging over an
    ankle on its foot."""
    scan, truth = _swollen_scan(_right_leg(2629, 1816406312), 23.068, 0.8669)
    fit = fit_scan(scan, FitOptions(side="right"))
    for name, tolerance in (("B", 2.0), ("C", 2.0), ("D", 4.0)):
        assert abs(fit.landmarks.tape_girths_mm[name] - truth.girths_mm[name]) < tolerance, name


def test_a_swollen_leg_without_a_calf_bulge_is_refused_saying_so():
    """Swollen 24 mm, fading 0.67 of the way up (benchmarks/swollen.py 40 19, case 22:
    subject index 1406's right leg): the calf is no wider than the ankle (C/B 1.00).  The
    refusal says the leg has no calf bulge and that a tape measures it."""
    scan, truth = _swollen_scan(_right_leg(1406, 1677656626), 24.174, 0.6661)
    assert truth.girths_mm["C"] < 1.02 * truth.girths_mm["B"]
    with pytest.raises(FitFailure) as caught:
        check_scan(scan, FitOptions(side="right"))
    assert caught.value.reason is FailureReason.NO_CALF
    assert "no calf bulge" in caught.value.detail and "by tape" in caught.value.detail, caught.value.detail


def test_a_stored_placement_finds_its_leg_whichever_half_it_names(female_body, tmp_path):
    """The fit replays the upload check's placement; the two halves of a pair of legs come
    in the order of the split's labels, which another release's split may turn round.
    The half holding the placed ankle is the leg, whichever half the placement names."""
    from app.geometry.placement.place import LegPlacement, replace_leg

    body, _ = female_body
    path = tmp_path / "two_legs.ply"
    _two_legs(body).export(path)
    scan = load_scan(path)
    placement = check_scan(scan, FitOptions(side="left"))
    assert placement.half in (0, 1)
    turned = LegPlacement.from_dict({**placement.to_dict(), "half": 1 - placement.half})
    assert np.array_equal(replace_leg(scan, turned).points, replace_leg(scan, placement).points)
