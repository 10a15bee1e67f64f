"""Placing a leg (app.geometry.placement): a side given against the evidence is kept
and said."""

from __future__ import annotations

from app.geometry.fit import FitOptions, check_scan
from app.geometry.scan_io import load_scan
from tests.conftest import REAL


def test_a_side_given_against_a_confident_foot_is_kept_with_a_warning():
    scan = load_scan(REAL / "bodyparts3d_right_leg.stl")
    inferred = check_scan(scan)
    assert inferred["side"] == "right" and inferred["side_confidence"] >= 0.9
    assert not any("foot in the scan looks like" in w for w in inferred["warnings"])
    given = check_scan(scan, FitOptions(side="left"))
    assert given["side"] == "left" and given["side_source"] == "given"
    warning = next(w for w in given["warnings"] if "given as left" in w)
    assert "right foot" in warning and "0.99" in warning and "medial and lateral" in warning
    agreed = check_scan(scan, FitOptions(side="right"))
    assert not any("given as" in w for w in agreed["warnings"])
