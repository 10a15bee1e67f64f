"""The paper's pipeline end to end (sections 2.1-2.6): a scan in, a NURBS calf and its
landmarks out, with the error index E (section 3) and the surface-to-scan distance.
"""

from __future__ import annotations

from app.geometry.fit.pipeline import (
    FitOptions,
    FitResult,
    check_scan,
    fit_calf,
    fit_placed_leg,
    fit_scan,
    place_scan,
)

__all__ = ["FitOptions", "FitResult", "check_scan", "fit_calf", "fit_placed_leg", "fit_scan", "place_scan"]
