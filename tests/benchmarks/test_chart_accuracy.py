"""benchmarks/chart_accuracy.py: which re-scan pairs count as read without a warning, and
where each seed's results go."""

from benchmarks.chart_accuracy import result_stem, unwarned_pairs, unwarned_readings, warned_about


def _scan(cg: float, **flags) -> dict:
    return {"outcome": "fit", "cG": cg, "lG": 700.0 + cg / 100, "uncertainty": flags.pop("uncertainty", {}), **flags}


def test_a_reading_the_record_warns_about_is_left_out_of_the_unwarned_pairs():
    leg = {"scans": {"mesh_clean": _scan(500.0), "noise": _scan(504.0, g_uncertain=True),
                     "cloud": _scan(501.0), "holes": _scan(503.0, uncertainty={"cG": 4.0}),
                     "two_legs": {"outcome": "no_knee"}}}
    # the smooth fold's warning (g_uncertain) and a stated uncertainty both leave a scan
    # out, for the girth and for its length
    assert sorted(unwarned_pairs([leg], "cG")) == [1.0]
    assert len(unwarned_pairs([leg], "lG")) == 1
    # and the table says how many readings the unwarned pairs stand on
    assert unwarned_readings([leg], "cG") == (2, 4)
    # a point with no warnings keeps every pair of the scans that fit: 4 scans, 6 pairs
    leg["scans"]["noise"]["g_uncertain"] = False
    leg["scans"]["holes"]["uncertainty"] = {}
    assert len(unwarned_pairs([leg], "cG")) == 6


def test_a_knee_waist_at_the_scans_edge_is_a_warning_about_cd_and_ld_only():
    scan = {"outcome": "fit", "at_scan_edge": ["D"]}
    assert warned_about(scan, "cD") and warned_about(scan, "lD") and not warned_about(scan, "cB") and not warned_about(scan, "lC")


def test_a_leg_whose_clean_scan_failed_has_no_pairs():
    leg = {"scans": {"mesh_clean": {"outcome": "no_calf"}, "noise": _scan(500.0), "cloud": _scan(501.0)}}
    assert unwarned_pairs([leg], "cG") == []
    assert unwarned_readings([leg], "cG") == (0, 0)


def test_a_held_out_seed_does_not_overwrite_the_development_seeds_results():
    assert result_stem(11) == "chart_accuracy"
    assert {result_stem(seed) for seed in (3, 5, 7, 9, 13)} == {f"chart_accuracy-seed{seed}" for seed in (3, 5, 7, 9, 13)}
