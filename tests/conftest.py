"""Shared fixtures: the vendored real meshes and cached fits of them."""

from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"
REAL = DATA / "real"

#: (file, side) of every real leg the tests use; +X is the subject's left in all files
REAL_LEGS = [
    ("bodyparts3d_right_leg.stl", None),
    ("vh_female_skin.glb", "left"),
    ("vh_female_skin.glb", "right"),
    ("vh_male_skin.glb", "left"),
    ("vh_male_skin.glb", "right"),
]

#: the scan axis pointing to the subject's front, per file (data README)
FRONT_AXIS = {"bodyparts3d_right_leg.stl": (0.0, -1.0, 0.0), "vh_female_skin.glb": (0.0, 0.0, 1.0), "vh_male_skin.glb": (0.0, 0.0, 1.0)}
UP_AXIS = {"bodyparts3d_right_leg.stl": (0.0, 0.0, 1.0), "vh_female_skin.glb": (0.0, 1.0, 0.0), "vh_male_skin.glb": (0.0, 1.0, 0.0)}


@pytest.fixture(scope="session")
def real_dir() -> Path:
    return REAL


_FITS: dict = {}


def fitted(file: str, side: str | None, points: int = 15):
    """Fit a vendored leg once per session (the fits are deterministic)."""
    from app.geometry.fit import FitOptions, fit_scan
    from app.geometry.scan_io import load_scan

    key = (file, side, points)
    if key not in _FITS:
        scan = load_scan(REAL / file)
        _FITS[key] = (scan, fit_scan(scan, FitOptions(side=side, points_per_layer=points)))
    return _FITS[key]
