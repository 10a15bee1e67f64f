"""The worker-side fitting service: the placement found by the upload check is reused,
and the leg it cut out is handed to the fit."""

import json

import numpy as np
import pytest

from app.geometry.errors import FailureReason, FitFailure
from app.services.fitting import fit_scan_file, parse_options, validate_scan_file
from tests.conftest import REAL


@pytest.mark.parametrize("file,side,fmt", [("bodyparts3d_right_leg.stl", None, "stl"), ("vh_male_skin.glb", "left", "glb")])
def test_a_fit_reusing_the_upload_check_equals_a_fresh_fit(file, side, fmt):
    options = parse_options(side, None, 8)
    placement = validate_scan_file(str(REAL / file), fmt, options)
    json.dumps(placement)  # stored as JSON in the job
    fresh = fit_scan_file(str(REAL / file), fmt, options)["record"]
    reused = fit_scan_file(str(REAL / file), fmt, options, placement)["record"]
    for key in ("surface", "frame", "landmarks", "layers", "side"):
        assert reused[key] == fresh[key], key
    assert reused["fit"]["error_index_exact"] == fresh["fit"]["error_index_exact"]
    # a single leg without a side: read from its foot (BodyParts3D is a right leg)
    assert placement["side"] == (side or "right") and np.isfinite(placement["c_mm"])


@pytest.mark.parametrize("file,side,fmt", [("bodyparts3d_right_leg.stl", None, "stl"), ("vh_female_skin.glb", "right", "glb")])
def test_the_leg_the_check_cut_out_is_fitted_as_the_scan_would_be_and_is_then_gone(file, side, fmt, tmp_path):
    options = parse_options(side, None, 15)
    leg_file = tmp_path / "upload-host-1-x.leg.npz"
    placement = validate_scan_file(str(REAL / file), fmt, options, placed_leg=str(leg_file))
    assert leg_file.is_file()
    from_scan = fit_scan_file(str(REAL / file), fmt, options, placement)
    # the scan path is wrong on purpose: a fit that read the scan would fail
    handed = fit_scan_file(str(tmp_path / "not-there"), fmt, options, placement, placed_leg=str(leg_file))
    assert not leg_file.exists()  # a hand-off: the fit that read it removed it
    for key in ("surface", "frame", "landmarks", "layers", "side", "chart", "scan"):
        assert handed["record"].get(key) == from_scan["record"].get(key), key
    assert handed["record"]["fit"]["error_index_exact"] == from_scan["record"]["fit"]["error_index_exact"]
    assert handed["stage_seconds"]["calf_frame"] == 0.0  # placed by the check, not again


def test_a_leg_cut_for_another_placement_or_unreadable_is_not_used(tmp_path):
    options = parse_options(None, None, 8)
    scan = str(REAL / "bodyparts3d_right_leg.stl")
    leg_file = tmp_path / "leg.npz"
    placement = validate_scan_file(scan, "stl", options, placed_leg=str(leg_file))
    moved = {**placement, "c_mm": placement["c_mm"] + 5.0}
    with pytest.raises(FitFailure):  # not the job's placement: the scan is read, and it is not there
        fit_scan_file(str(tmp_path / "not-there"), "stl", options, moved, placed_leg=str(leg_file))
    assert not leg_file.exists()
    leg_file.write_bytes(b"not a leg")
    record = fit_scan_file(scan, "stl", options, placement, placed_leg=str(leg_file))["record"]
    assert record["side"] == "right" and not leg_file.exists()


@pytest.mark.parametrize("args,words", [(("up", None, None), "side"), ((None, "inch", None), "units"),
                                        ((None, None, "many"), "integer"), ((None, None, 2), "points")])
def test_upload_options_are_validated(args, words):
    with pytest.raises(FitFailure) as info:
        parse_options(*args)
    assert info.value.reason == FailureReason.INVALID_OPTION and words in info.value.detail
