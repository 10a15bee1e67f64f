"""A small fixed subset of the robustness corpus (benchmarks/corpus), made at test time.

Each case is a generated scan with an independent truth (tape girths measured on the
clean MakeHuman mesh); the fitting core must give the expected outcome and, when it
fits, tape girths at B and C within 2 mm of the truth and at D within 4 mm (the
issue's targets).
"""

from __future__ import annotations

import pytest

from benchmarks.corpus.cases import build_case, corpus_specs
from benchmarks.corpus.evaluate import run_case

#: end to end and slow: `make test-slow` (and .ci/run) runs it, `make test` does not
pytestmark = pytest.mark.slow

#: one or two cases of the kinds a clinic sends most (seeded: always the same scans)
SUBSET = ["mesh_clean-00", "knee_high-00", "knee_high_cloud-00", "ankle_to_thigh-00", "holes-00",
          "cloud-00", "cloud_noise-00", "cloud_outliers-00", "cloud_uneven-00", "cloud_holes-00",
          "floor_cloud-00", "two_legs-00", "two_legs_no_side-00", "fragment-00", "cut_below_knee-00",
          "cut_above_ankle-00", "vertex_cloud-00", "coarse_mesh-00", "body_vertices-00",
          "sparse_leg_vertices-00"]
SPECS = {s.case_id: s for s in corpus_specs(60)}


@pytest.mark.parametrize("case_id", SUBSET)
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


def test_several_legs_are_listed_in_the_failure():
    result = run_case(build_case(SPECS["two_legs_no_side-00"]))
    assert result["outcome"] == "several_legs"
    assert "left leg" in result["detail"] and "right leg" in result["detail"] and "side=" in result["detail"]


def test_the_generator_is_deterministic():
    a, b = build_case(SPECS["cloud-00"]), build_case(SPECS["cloud-00"])
    assert a.data == b.data and a.truth.girths_mm == b.truth.girths_mm


@pytest.mark.parametrize("case_id", ["seated-00", "seated-02", "seated-03"])
def test_a_seated_leg_is_measured_along_its_shank(case_id):
    """Knees bent 56, 32 and 84 degrees (specs of the 220-case corpus), foot to hip."""
    case = build_case({s.case_id: s for s in corpus_specs(220)}[case_id])
    assert case.expect == "fit"
    result = run_case(case)
    assert result["outcome"] == "fit", result.get("detail")
    for name in ("B", "C"):
        assert abs(result["girth_error_mm"][name]) <= 2.0, (name, result["girth_error_mm"])


@pytest.mark.parametrize("case_id", ["cut_below_knee-00", "cut_below_knee-03", "ankle_to_thigh-05"])
def test_a_crop_names_what_is_really_missing(case_id):
    """A scan from the foot to below the knee waist lacks the knee (the foot is not read as
    a calf upside down); a scan cut at the ankle minimum B is fitted, B at its edge."""
    case = build_case({s.case_id: s for s in corpus_specs(220)}[case_id])
    result = run_case(case)
    assert result["outcome"] == case.expect, result.get("detail")


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
