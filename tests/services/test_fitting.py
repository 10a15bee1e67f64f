"""The worker-side fitting service: the placement found by the upload check is reused."""

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


@pytest.mark.parametrize("args,words", [(("up", None, None), "side"), ((None, "inch", None), "units"),
                                        ((None, None, "many"), "integer"), ((None, None, 2), "points")])
def test_upload_options_are_validated(args, words):
    with pytest.raises(FitFailure) as info:
        parse_options(*args)
    assert info.value.reason == FailureReason.INVALID_OPTION and words in info.value.detail
