"""benchmarks/record_diff.py: what counts as a changed record."""

from benchmarks.record_diff import differences


def test_a_change_beyond_1e9_relative_a_missing_key_and_a_new_string_are_found_and_timings_are_not():
    before = {"fit": {"error_index": 0.0105, "seconds": 0.4, "stage_seconds": {"error": 0.1}},
              "landmarks": {"B": {"tape_girth_mm": 214.0}}, "side": "right", "layers": [1.0, 2.0]}
    same = {"fit": {"error_index": 0.0105 * (1 + 5e-10), "seconds": 9.0, "stage_seconds": {"error": 3.0}},
            "landmarks": {"B": {"tape_girth_mm": 214.0}}, "side": "right", "layers": [1.0, 2.0]}
    assert differences(before, same) == []
    moved = {**same, "landmarks": {"B": {"tape_girth_mm": 214.1}}, "side": "left", "layers": [1.0], "leg_model": {}}
    found = dict(differences(before, moved))
    assert set(found) == {"/landmarks/B/tape_girth_mm", "/side", "/layers", "/leg_model"}
    assert "4.7e-04 relative" in found["/landmarks/B/tape_girth_mm"] and found["/leg_model"] == "only in the second"
    assert differences(float("nan"), float("nan")) == [] and differences("paper", "lsq") != []
