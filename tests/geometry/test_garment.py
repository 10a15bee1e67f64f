"""Stocking designs (app.geometry.garment.design): targets met, graded, refused with a reason."""

from dataclasses import replace

import numpy as np
import pytest
import trimesh

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.fit.pipeline import FitOptions, fit_scan
from app.geometry.garment.design import DesignInputs, design_stocking
from app.geometry.garment.fabric import Fabric
from app.geometry.garment.pressure import PA_PER_MMHG
from app.geometry.garment.standards import normalize_class
from app.geometry.scan.reader import load_scan
from tests.conftest import fitted
from tests.phantoms import paper_tube as tube

LANDMARKS = {"B": {"height_mm": 0.0}, "B1": {"height_mm": 80.0}, "C": {"height_mm": 180.0}, "D": {"height_mm": 280.0}}


def test_a_linear_tension_table_reproduces_the_stiffness():
    surface = tube(45.0, 38.0)
    linear = design_stocking(surface, LANDMARKS, "right", DesignInputs(fabric=Fabric.linear(12.0)))
    table = design_stocking(surface, LANDMARKS, "right", DesignInputs(fabric=Fabric.table([0.0, 0.3, 0.6, 1.0], [0.0, 3.6, 7.2, 12.0])))
    a, b = linear.knitting_spec, table.knitting_spec
    assert np.allclose(a.relaxed_circumference_mm, b.relaxed_circumference_mm, atol=1e-6)
    assert np.allclose(a.tension_n_per_cm, b.tension_n_per_cm, rtol=1e-6)
    fabric = Fabric.table([0.1, 0.5, 0.9], [1.0, 4.0, 12.0])
    strains = np.array([0.1, 0.3, 0.7, 0.9])
    assert np.allclose(fabric.strain_for(fabric.tension(strains)), strains)


def test_design_meets_its_targets_and_grades_down_the_leg():
    surface = tube(33.0, 30.0)
    result = design_stocking(surface, LANDMARKS, "left", DesignInputs(compression_class="II", fabric=Fabric.linear(8.0)))
    b = result.landmarks["B"]
    assert 23 <= b.mean_pressure_mmhg <= 32
    assert b.mean_pressure_mmhg == pytest.approx(27.5, abs=0.5)  # the middle of class II
    p = [result.landmarks[n].mean_pressure_mmhg for n in ("B", "B1", "C", "D")]
    assert p[0] > p[1] > p[2] > p[3]
    assert result.ratios["D/B"] == pytest.approx(0.5, abs=0.02)
    assert result.passed and not result.side_assumed
    spec = result.knitting_spec
    assert set(np.arange(0.0, 281.0, 5.0)) <= set(np.round(spec.heights_mm, 6))  # every 5 mm from B to D
    assert {0.0, 80.0, 180.0, 280.0} <= set(np.round(spec.heights_mm, 6))  # and at the landmarks
    # L0 = L / (1 + eps), eps = T / K, T = P L / (2 pi), knitted to 1 mm
    L = spec.stretched_circumference_mm
    expected = np.round(L / (1 + spec.target_mmhg * PA_PER_MMHG * L / (2 * np.pi * 1e5) / 8.0))
    assert np.allclose(spec.relaxed_circumference_mm, expected, atol=1.0)


def test_explicit_targets_and_other_standards():
    surface = tube(33.0, 30.0)
    explicit = design_stocking(surface, LANDMARKS, None, DesignInputs(targets_mmhg={"B": 30, "B1": 25, "C": 20, "D": 12}, fabric=Fabric.linear(10)))
    assert explicit.landmarks["C"].mean_pressure_mmhg == pytest.approx(20, abs=0.5)
    assert explicit.compression_class is None and explicit.side_assumed
    assert normalize_class("bs", "class 2")[1:] == ("2", (18.0, 24.0))
    assert normalize_class("AFNOR", "III")[1] == "3"
    assert normalize_class("RAL", "ccl4")[2] == (49.0, None)


@pytest.mark.parametrize(
    "inputs,reason",
    [
        (dict(compression_class="IV", fabric=Fabric(stiffness_n_per_cm=1.0)), FailureReason.UNREACHABLE_PRESSURE),
        (dict(compression_class="III", fabric=Fabric(strains=(0.0, 0.05), tensions_n_per_cm=(0.0, 1.0), max_strain=0.05)), FailureReason.UNREACHABLE_PRESSURE),
        (dict(fabric=Fabric(stiffness_n_per_cm=-3.0)), FailureReason.INVALID_FABRIC),
        (dict(fabric=Fabric(stiffness_n_per_cm=5000.0)), FailureReason.INVALID_FABRIC),
        (dict(fabric=Fabric(strains=(0.0, 0.5, 0.4), tensions_n_per_cm=(0.0, 2.0, 3.0))), FailureReason.INVALID_FABRIC),
        (dict(compression_class="VII"), FailureReason.INVALID_TARGET),
        (dict(standard="ISO"), FailureReason.INVALID_TARGET),
        (dict(targets_mmhg={"B": 30, "B1": -5, "C": 20, "D": 10}), FailureReason.INVALID_TARGET),
        (dict(targets_mmhg={"B": 30, "C": 20, "D": 10}), FailureReason.INVALID_TARGET),
        (dict(hot_spot_limit_mmhg=-1), FailureReason.INVALID_TARGET),
    ],
)
def test_bad_designs_are_refused_with_a_reason(inputs, reason):
    with pytest.raises(FitFailure) as info:
        design_stocking(tube(33.0, 30.0), LANDMARKS, "right", DesignInputs(**inputs))
    assert info.value.reason == reason and info.value.detail


@pytest.mark.parametrize("file,side", [("bodyparts3d_right_leg.stl", None), ("vh_female_skin.glb", "left"),
                                       ("vh_female_skin.glb", "right"), ("vh_male_skin.glb", "left"), ("vh_male_skin.glb", "right")])
def test_real_legs_meet_class_ii_at_b_and_grade_down(file, side):
    _, result = fitted(file, side)
    landmarks = result.landmarks.as_dict()
    design = design_stocking(result.surface, landmarks, side or "right", DesignInputs(compression_class="II", fabric=Fabric.linear(10.0)))
    p = {n: design.landmarks[n].mean_pressure_mmhg for n in ("B", "B1", "C", "D")}
    assert 23 <= p["B"] <= 32
    assert p["B"] > p["B1"] > p["C"] > p["D"]
    assert design.passed
    # local pressures vary around the leg (the paper's Table 1): tendons and the tibia carry more
    sides = design.landmarks["B"].sides_pa
    assert max(sides.values()) > 1.2 * min(sides.values())
    assert all(v >= 0 for v in sides.values())


def test_the_verdict_is_pass_only_without_failed_checks_and_hot_spots():
    """fail on a normative check, review on an advisory check or a hot spot (with where
    it is), pass only when nothing is left to look at."""
    from app.geometry.garment.design import DesignCheck, design_verdict
    from app.geometry.garment.pressure import HotSpot

    normative = DesignCheck("B in RAL class II", 27.0, True, True)
    advisory = DesignCheck("C 50-80% of B", 0.6, True, False)
    spot = HotSpot(height_mm=120.0, from_height_mm=110.0, to_height_mm=131.0, angle_deg=90.0, side="anterior",
                   peak_pa=63.8 * PA_PER_MMHG, samples=12)
    assert design_verdict([normative, advisory], [], 60.0) == ("pass", [])
    verdict, reasons = design_verdict([normative, advisory], [spot], 60.0)
    assert verdict == "review" and "63.8 mmHg above the 60 mmHg limit at 120 mm above B" in reasons[0]
    assert design_verdict([normative, replace(advisory, passed=False)], [], 60.0)[0] == "review"
    assert design_verdict([replace(normative, passed=False), advisory], [spot], 60.0)[0] == "fail"


def test_a_thigh_high_graded_from_an_uncertain_girth_is_for_review():
    """The BodyParts3D leg reaches its gluteal fold (a crease: no uncertainty): its AG
    design passes or not on its checks alone; the same record whose chart says cG is
    uncertain by 7 mm (a smooth fold, app.geometry.anatomy.thigh) gives "review" with
    the point named, and a knee-high, which is not graded from cG, is not affected; an
    uncertain cA (a sparse foot, app.geometry.anatomy.foot_loops) is for review on both."""
    from app.records.codec import record_from_fit

    scan, result = fitted("bodyparts3d_right_leg.stl", None)
    record = record_from_fit(result, scan.source_format, scan.units)
    assert all("uncertainty_mm" not in record.chart[name] for name in ("cE", "cF", "cG"))
    inputs = DesignInputs(compression_class="II", fabric=Fabric.linear(10.0), stocking_type="AG")
    sure = design_stocking(record.surface, record.landmarks, "right", inputs, record.chart)
    assert sure.uncertain_inputs == () and not any("uncertain" in r for r in sure.verdict[1])
    chart = {**record.chart, "cG": {**record.chart["cG"], "uncertainty_mm": 6.6}}
    unsure = design_stocking(record.surface, record.landmarks, "right", inputs, chart)
    verdict, reasons = unsure.verdict
    assert verdict in ("review", "fail") and "cG is uncertain by about 7 mm" in reasons[-1]
    if sure.verdict[0] == "pass":
        assert verdict == "review"
    knee_high = design_stocking(record.surface, record.landmarks, "right", DesignInputs(compression_class="II"), chart)
    assert knee_high.uncertain_inputs == ()
    # every stocking has a foot knitted from cA and cY: a sparse foot's cA is for review on both
    sparse_foot = {**record.chart, "cA": {**record.chart["cA"], "uncertainty_mm": 12.4}}
    for stocking_type in ("AD", "AG"):
        design = design_stocking(record.surface, record.landmarks, "right",
                                 replace(inputs, stocking_type=stocking_type), sparse_foot)
        assert design.uncertain_inputs == ("cA is uncertain by about 12 mm (the record's warnings say why): "
                                           "take cA by tape (RAL-GZ 387) before knitting",)
        assert design.verdict[0] in ("review", "fail")


def test_a_design_from_a_surface_off_the_skin_is_for_review():
    """The record's own surface -> scan distances (fit.surface_to_scan): BodyParts3D's
    calf surface lies on the skin, so its design is judged on its checks alone; the same
    surface said to stand 4.3 mm off over 6% of a ring (the fit's off-skin warning, at
    least 5% of a ring) gives "review" with where."""
    from app.records.codec import record_from_fit

    scan, result = fitted("bodyparts3d_right_leg.stl", None)
    record = record_from_fit(result, scan.source_format, scan.units)
    skin = record.fit["surface_to_scan"]
    inputs = DesignInputs(compression_class="II", fabric=Fabric.linear(10.0))
    on_skin = design_stocking(record.surface, record.landmarks, "right", inputs, record.chart, record.fit)
    assert skin["worst_ring_share"] < 0.05 and on_skin.uncertain_inputs == ()
    off = {**skin, "worst_ring_share": 0.06, "max_mm": 4.3, "worst_ring_height_mm": 326.0}
    verdict, reasons = design_stocking(record.surface, record.landmarks, "right", inputs, record.chart,
                                       {**record.fit, "surface_to_scan": off}).verdict
    assert verdict in ("review", "fail") and any("stands up to 4.3 mm off the scan's skin" in r and "326 mm above B" in r
                                                 for r in reasons)
    if on_skin.verdict[0] == "pass":
        assert verdict == "review"
    # an imported record's fit is its own: distances that are not such a dict are no reason
    for junk in ("far", {"worst_ring_share": "x"}, {**skin, "max_mm": None}):
        fit = {**record.fit, "surface_to_scan": junk}
        assert design_stocking(record.surface, record.landmarks, "right", inputs, record.chart, fit).uncertain_inputs == ()
    assert design_stocking(record.surface, record.landmarks, "right", inputs, record.chart, "junk").uncertain_inputs == ()


def test_a_thigh_high_from_a_sparse_cloud_is_for_review(tmp_path):
    """BodyParts3D's leg clustered to 8 mm and sent as its 4.4k vertices: the fit says the
    cloud is sparse and the record keeps its density (fit.sparse_points_per_mm); a
    thigh-high designed from it is "review", naming the thigh's points to take by tape (a
    body's sparse vertices read cE-cG 3-5 mm off, and G once 150 mm low), a knee-high is
    not affected, and the leg's mesh record carries no such flag."""
    from app.records.codec import record_from_fit
    from benchmarks.corpus.degrade import coarsen

    scan, result = fitted("bodyparts3d_right_leg.stl", None)
    assert "sparse_points_per_mm" not in record_from_fit(result, scan.source_format, scan.units).fit
    vertices, _ = coarsen(scan.points_mm, scan.faces, 8.0)
    path = tmp_path / "vertices.ply"
    trimesh.PointCloud(vertices).export(path)
    cloud = load_scan(path)
    record = record_from_fit(fit_scan(cloud, FitOptions()), cloud.source_format, cloud.units)
    sparse = record.fit["sparse_points_per_mm"]
    assert 1.0 < sparse < 5.0 and any("the cloud is sparse" in w for w in record.warnings)
    inputs = DesignInputs(compression_class="II", fabric=Fabric.linear(10.0), stocking_type="AG")
    thigh_high = design_stocking(record.surface, record.landmarks, "right", inputs, record.chart, record.fit)
    verdict, reasons = thigh_high.verdict
    assert verdict in ("review", "fail") and any("sparse cloud" in r and "cG" in r for r in reasons)
    knee_high = design_stocking(record.surface, record.landmarks, "right", DesignInputs(compression_class="II"),
                                record.chart, record.fit)
    for junk in ("dense", -1.0, float("nan"), True):  # an imported record's own entry is no reason
        imported = design_stocking(record.surface, record.landmarks, "right", inputs, record.chart,
                                   {**record.fit, "sparse_points_per_mm": junk})
        assert not any("sparse cloud" in r for r in imported.uncertain_inputs)
    assert not any("sparse cloud" in r for r in knee_high.uncertain_inputs)
