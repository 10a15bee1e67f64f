"""The options of a fit (:class:`FitOptions`): which leg, the paper's m, the resampling,
the surface's mode and the lsq grid; validated before any work (a typed FitFailure
INVALID_OPTION naming the bad one)."""

from __future__ import annotations

from dataclasses import dataclass

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.spline.lsq import LsqGrid

SURFACE_MODES = ("paper", "paper_stacked", "lsq")

@dataclass(frozen=True)
class FitOptions:
    """Options of a fit.

    side : "left" | "right" | None  - which leg of a body; recorded for a leg scan.
    points_per_layer : m, the shared feature angles per layer (paper: 8 or 15).
    n_sections : resampled sections between B and D (paper: 200).
    section_spacing_mm : if given, sections every this many mm instead (e.g. 1.0).
    n_angles : rays per section (paper: 72, i.e. 5 degrees).
    mode : "paper" (7 x m interpolation), "paper_stacked", or "lsq" (least squares on
        all the calf's points, :mod:`app.geometry.spline.lsq`).
    grid : the lsq control net, "ALONGxAROUND" (default 7x15, the paper's 105 points).
    """

    side: str | None = None
    points_per_layer: int = 15
    n_sections: int = 200
    section_spacing_mm: float | None = None
    n_angles: int = 72
    mode: str = "paper"
    grid: str = "7x15"

    def validate(self) -> None:
        if self.side not in (None, "left", "right"):
            raise FitFailure(FailureReason.INVALID_OPTION, f"side must be left or right, not {self.side!r}")
        if not 4 <= self.points_per_layer <= 36:
            raise FitFailure(FailureReason.INVALID_OPTION, "points per layer must be between 4 and 36 (paper: 8 or 15)")
        if not 20 <= self.n_sections <= 2000:
            raise FitFailure(FailureReason.INVALID_OPTION, "sections must be between 20 and 2000")
        if self.section_spacing_mm is not None and not 0.2 <= self.section_spacing_mm <= 20:
            raise FitFailure(FailureReason.INVALID_OPTION, "section spacing must be 0.2-20 mm")
        if self.mode not in SURFACE_MODES:
            raise FitFailure(FailureReason.INVALID_OPTION, f"mode must be one of {', '.join(SURFACE_MODES)}")
        if self.mode == "lsq":
            LsqGrid.parse(self.grid)
        if self.n_angles not in (36, 72, 144, 360):
            raise FitFailure(FailureReason.INVALID_OPTION, "angles per section must be 36, 72, 144 or 360")
