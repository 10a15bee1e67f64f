"""A small fixed subset of the robustness corpus (benchmarks/corpus), made at test time.

Each case is a generated scan with an independent truth (tape girths measured on the
clean MakeHuman mesh); the fitting core must give the expected outcome and, when it
fits, tape girths at B and C within 2 mm of the truth and at D within 4 mm (the
issue's targets).
"""

from __future__ import annotations

import numpy as np
import pytest

from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan
from app.geometry.garment.measuring_points import chart_of_record
from app.geometry.placement.place import TOUCHING_LEGS_WARNING
from app.geometry.scan.reader import load_scan
from app.records.codec import record_from_fit
from benchmarks.chart_accuracy import RESCAN_KINDS, chart_points
from benchmarks.corpus.cases import CaseSpec, build_case, corpus_specs, leg_rescans
from benchmarks.corpus.evaluate import run_case
from benchmarks.sole import NO_FLOOR, sole_row

#: end to end and slow: `make test-slow` (and .ci/run) runs it, `make test` does not
pytestmark = pytest.mark.slow

#: one or two cases of the kinds a clinic sends most (seeded: always the same scans)
SUBSET = ["mesh_clean-00", "knee_high-00", "knee_high_cloud-00", "ankle_to_thigh-00", "holes-00",
          "cloud-00", "cloud_noise-00", "cloud_outliers-00", "cloud_uneven-00", "cloud_holes-00",
          "floor_cloud-00", "two_legs-00", "two_legs_no_side-00", "fragment-00", "cut_below_knee-00",
          "cut_above_ankle-00", "vertex_cloud-00", "coarse_mesh-00", "body_vertices-00",
          "sparse_leg_vertices-00"]
SPECS = {s.case_id: s for s in corpus_specs(60)}


#: cases the service still gets wrong, each said in the README's "what still fails"; strict,
#: so a case that starts passing fails here until it is moved back
#: (sparse_leg_vertices-00, 5.5k vertices of a lower leg ending 28 mm above its knee waist
#: D, was refused no_knee along a first axis its dense foot had pulled 20 degrees off the
#: shank; read again along the consensus line of the compact slabs' centroids it fits:
#: app.geometry.placement.leg_axis._consensus_reading)
KNOWN_WRONG: dict[str, str] = {}


@pytest.mark.parametrize("case_id", [pytest.param(c, marks=pytest.mark.xfail(reason=KNOWN_WRONG[c], strict=True))
                                     if c in KNOWN_WRONG else c for c in SUBSET])
def test_generated_scan_gives_the_right_outcome(case_id):
    case = build_case(SPECS[case_id])
    result = run_case(case)
    assert result["outcome"] == case.expect, result.get("detail")
    if result["outcome"] == "fit":
        for name in ("B", "C"):
            assert abs(result["girth_error_mm"][name]) <= 2.0, (name, result["girth_error_mm"])
        # the knee waist is read on a plane perpendicular to the shank's long axis
        assert abs(result["girth_error_mm"]["D"]) <= 4.0, result["girth_error_mm"]
        if case.spec.kind.startswith("ankle_to_thigh"):
            assert "B" in result["at_scan_edge"]
        assert result["warnings"] is not None


def test_two_legs_in_a_coarse_mesh_are_cut_apart_on_its_triangles():
    """Seed 17's coarse_mesh-01 (the hold-out corpus): both legs, feet to hips, in 6.5k
    triangles whose vertices lie 21 mm apart (p95).  Split on its vertices alone, the
    occupancy pixel merged the two shins and the pair was refused as a partial view of one
    leg; split on its triangles, the leg asked for is measured within 2 mm."""
    case = build_case({s.case_id: s for s in corpus_specs(220, 17)}["coarse_mesh-01"])
    result = run_case(case)
    assert result["outcome"] == "fit", result.get("detail")
    assert max(abs(e) for e in result["girth_error_mm"].values()) <= 2.0, result["girth_error_mm"]
    assert result["side_found"] == case.true_side


@pytest.mark.parametrize("case_id", ["sparse_leg_vertices-02", "sparse_leg_vertices-04"])
def test_a_sparse_knee_high_scan_keeps_the_sections_below_its_cut_that_it_sees_all_round(case_id):
    """5.5k vertices of a lower leg cut 13-20 mm above D at the cut's lowest edge, where
    the girth has risen by a tape's 2 mm 10-12 mm above D: the sparse cloud sees 65-89%
    of every section's bins, so on coverage alone the last 25 mm below the cut were all
    taken for the cut's partial sections, the rise above D with them, and the scan was
    refused no_knee.  A section is partial where it misses a whole arc, as a cut leaves."""
    case = build_case({s.case_id: s for s in corpus_specs(220, 23)}[case_id])
    assert case.notes["top_above_D_mm"] - case.notes["cut_drop_at_knee_mm"] > case.notes["knee_rise_mm"]
    result = run_case(case)
    assert result["outcome"] == "fit", result.get("detail")
    assert max(abs(e) for e in result["girth_error_mm"].values()) <= 2.0, result["girth_error_mm"]
    assert abs(result["height_error_mm"]["D"]) <= 5.0, result["height_error_mm"]


@pytest.mark.parametrize("seed,case_id", [(17, "sparse_leg_vertices-00"), (19, "sparse_leg_vertices-01")])
def test_a_sparse_lower_leg_whose_slabs_leave_c_open_is_fitted_on_its_graph(seed, case_id):
    """5.5k vertices of a lower leg, 2.5 points per mm of the calf: every 20 mm slab
    within 12 mm of C missed a 120-degree arc of the back (the body mesh's long
    triangles), and the cloud was refused too_sparse.  C's layer read where the
    neighbour graph's edges cross its plane (app.geometry.fit.sparse_clouds.open_sections_on_graph),
    the leg is measured within 2 mm at B and C and 4 mm at D."""
    result = run_case(build_case({s.case_id: s for s in corpus_specs(220, seed)}[case_id]))
    assert result["outcome"] == "fit", result.get("detail")
    assert max(abs(result["girth_error_mm"][name]) for name in ("B", "C")) <= 2.0, result["girth_error_mm"]
    assert abs(result["girth_error_mm"]["D"]) <= 4.0, result["girth_error_mm"]


def test_several_legs_are_listed_in_the_failure():
    result = run_case(build_case(SPECS["two_legs_no_side-00"]))
    assert result["outcome"] == "several_legs"
    assert "left leg" in result["detail"] and "right leg" in result["detail"] and "side=" in result["detail"]


def test_the_generator_is_deterministic():
    a, b = build_case(SPECS["cloud-00"]), build_case(SPECS["cloud-00"])
    assert a.data == b.data and a.truth.girths_mm == b.truth.girths_mm


@pytest.mark.parametrize("case_id", ["seated-00", "seated-02", "seated-03"])
def test_a_seated_leg_is_measured_along_its_shank(case_id):
    """Knees bent 42, 51 and 74 degrees (specs of the 220-case corpus, seed 7), foot to
    hip, read straight (no cut at the knee): B and C within 2 mm, and the record says that
    cD, lC and lD were read on a bent knee."""
    case = build_case({s.case_id: s for s in corpus_specs(220)}[case_id])
    assert case.expect == "fit"
    result = run_case(case)
    assert result["outcome"] == "fit", result.get("detail")
    for name in ("B", "C"):
        assert abs(result["girth_error_mm"][name]) <= 2.0, (name, result["girth_error_mm"])
    assert [w for w in result["warnings"] if "cD and lD are read at the waist of a bent knee" in w]


@pytest.mark.parametrize("seed, case_id", [(11, "seated-02"), (7, "seated-01")])
def test_a_leg_seated_with_its_knee_waist_under_its_thigh_is_refused_for_its_bent_knee(seed, case_id):
    """Knees bent 86-87 degrees (the 220-case corpus), foot to hip, refused knee_bent,
    asking for the leg straight.  Seed 11 seated-02: the straight axis places the calf,
    but the planes of C and D cut the buttock and the thigh too (it was refused
    partial_view, "scan all round the leg", which it was).  Seed 7 seated-01: the main
    axis is the L's diagonal and its centre line follows neither limb (it was refused
    no_calf, "a foot, not a calf" of 929 mm girth); followed along the surface, the shank
    is cut free of the thigh, shows its ankle and calf, and the knee waist the thigh
    covers is named."""
    case = build_case({s.case_id: s for s in corpus_specs(220, seed)}[case_id])
    assert case.truth.knee_hidden
    result = run_case(case)
    assert result["outcome"] == "knee_bent", result.get("detail")
    assert "knee straight" in result["detail"]


def test_two_legs_standing_feet_together_are_cut_apart_and_measured():
    """A pair of legs turned about the hips until they touch below the knees, and 0.4
    degrees further (their skins pass into each other, where a body's would press flat;
    benchmarks/legs_together.py, pair 0 of seed 41, as a mesh and as a cloud): no air
    between the shins, so the blobs of the two-leg split merged and the pair was refused
    as a partial view of one leg.  Cut apart at their waists, the leg asked for is
    measured within 2 mm, and the record says the legs touched."""
    from benchmarks.legs_together import pair_cases

    cases = {c.spec.case_id: c for c in pair_cases(0, np.random.default_rng(41))}
    for case_id in ("pair00-pressed-mesh", "pair00-pressed-cloud"):
        result = run_case(cases[case_id])
        assert result["outcome"] == "fit", (case_id, result.get("detail"))
        assert max(abs(e) for e in result["girth_error_mm"].values()) <= 2.0, (case_id, result["girth_error_mm"])
        assert TOUCHING_LEGS_WARNING in result["warnings"]


@pytest.mark.parametrize("case_id", ["cut_below_knee-00", "cut_below_knee-03", "ankle_to_thigh-05"])
def test_a_crop_names_what_is_really_missing(case_id):
    """A scan from the foot to below the knee waist lacks the knee (the foot is not read as
    a calf upside down); a scan cut at the ankle minimum B is fitted, B at its edge."""
    case = build_case({s.case_id: s for s in corpus_specs(220)}[case_id])
    result = run_case(case)
    assert result["outcome"] == case.expect, result.get("detail")


def test_a_straight_legs_crop_is_never_measured_on_a_shank_read_in_its_thigh():
    """A straight leg cropped just below its ankle minimum (the 220-case corpus, seed 17,
    ankle_to_thigh-04) that no main-axis reading places: its geodesic centre line bends 12
    degrees at the knee, and read as a shank cut there, its thigh was fitted as a calf
    110-183 mm off (a reading that fitted, not one that refused).  The geodesic line only
    tells why a knee bent 45 degrees or more is refused; this crop keeps the refusal the
    straight reading gave, its missing ankle."""
    case = build_case({s.case_id: s for s in corpus_specs(220, 17)}["ankle_to_thigh-04"])
    result = run_case(case)
    assert result["outcome"] == "no_ankle", (result["outcome"], result.get("girth_error_mm"), result.get("detail"))


def test_a_scan_cut_below_its_knee_waist_says_the_waist_may_be_thinner():
    """A leg cut 52 mm below its knee waist whose girth levels off into the cut (the
    robustness corpus's cut_below_knee-02, seed 7) is fitted with D at the scan's edge: its
    cD is the edge's girth, which can only be the waist's or more (9 mm more here), and
    the record says the waist may be thinner and higher."""
    spec = {s.case_id: s for s in corpus_specs(220, 7)}["cut_below_knee-02"]
    result = run_case(build_case(spec))
    assert result["outcome"] == "fit" and "D" in result["at_scan_edge"]
    assert result["girth_error_mm"]["D"] > 0.0
    assert any("may be thinner than cD and higher than lD" in w for w in result["warnings"])


def test_the_floor_of_a_leg_scanned_with_strays_cut_through_the_foot_and_pointed():
    """One generated leg (leg seed 0) scanned clean, as a cloud with a scanner's stray
    points, cut 30-50 mm above the sole and with its foot pointed 20-45 degrees, fitted as
    an upload is and read as the record's chart: the strays leave lB within 2 mm of the
    clean scan's (the heel's plain lowest point read it 8.5 mm long), and the cut and
    the pointed foot give no length, each saying why (they read 40-60 mm short and
    5-20 mm long)."""
    chart, rows = {}, {}
    for kind, seed in (("mesh_clean", 100), ("cloud_outliers", 200), ("midfoot_midthigh", 300), ("plantar", 400)):
        case = build_case(CaseSpec(f"floor-{kind}", kind, seed, 1000, leg_seed=0))
        scan = load_scan(case.data, file_type=case.file_type, units=case.units)
        rows[kind] = sole_row(kind, kind, scan, case.side)
        if kind in NO_FLOOR:
            options = FitOptions(side=case.side)
            record = record_from_fit(fit_scan(scan, options, check_scan(scan, options)), scan.source_format, scan.units)
            chart[kind] = {m.point.name: m for m in chart_of_record(record.landmarks, record.scan.get("sole_mm"), "AG",
                                                                    record.chart, record.scan.get("sole_reason"))}
    clean = rows["mesh_clean"]["lB"]
    strays = rows["cloud_outliers"]
    assert abs(strays["lB"] - clean) < 2.0 and abs(strays["lB_lowest_point"] - clean) > 5.0, strays
    for kind, why in (("midfoot_midthigh", "cut through the foot"), ("plantar", "the foot is pointed")):
        assert rows[kind]["lB"] is None and why in rows[kind]["reason"]
        for point in ("lB", "lC", "lD", "foot_length", "cA", "cY"):
            assert chart[kind][point].value_mm is None and why in chart[kind][point].reason, (kind, point)


def test_a_streak_off_the_toes_among_a_floors_strays_is_not_the_foots_end():
    """chart_accuracy 8 19, leg 3, cloud_outliers: a scanner's streak runs 30 mm on from
    the toes along the floor among the floor's stray points, which spread its points'
    nearest off one line; it passed as skin and held the foot's end - the foot read 30 mm
    long and cA 5 mm short, unwarned (app.geometry.anatomy.skin_points.on_a_line).  The
    re-scan reads the clean mesh's foot."""
    specs = {(leg, spec.kind): spec for leg, spec in leg_rescans(8, 19, ("mesh_clean",) + RESCAN_KINDS) if leg == 3}
    readings = {}
    for kind in ("mesh_clean", "cloud_outliers"):
        case = build_case(specs[3, kind])
        readings[kind] = chart_points(load_scan(case.data, file_type=case.file_type, units=case.units), case.side)
    clean, streaked = readings["mesh_clean"], readings["cloud_outliers"]
    assert streaked["foot_length"] == pytest.approx(clean["foot_length"], abs=2.0)
    assert streaked["cA"] == pytest.approx(clean["cA"], abs=1.5)
