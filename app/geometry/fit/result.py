"""What the pipeline (:mod:`app.geometry.fit.pipeline`) produced for one scan: the NURBS
calf, its frame, landmarks, sections and error index, and the order form's points off
the calf (the foot, the thigh) with the leg's model above the calf.  Calf-frame mm
unless stated.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from app.geometry.anatomy.feature_layers import Landmarks
from app.geometry.anatomy.foot import FootMeasures
from app.geometry.anatomy.thigh import ThighMeasures
from app.geometry.fit.leg_model import LegModelOutcome
from app.geometry.fit.options import FitOptions
from app.geometry.placement import calf_frame as cf
from app.geometry.placement.leg_placement import LegPlacement
from app.geometry.scan.skin_layers import SkinLayers
from app.geometry.scan.skin_seam import SkinSeam
from app.geometry.sections import PolarSections
from app.geometry.spline.distance import SurfaceError
from app.geometry.spline.lsq import LsqFit
from app.geometry.spline.nurbs import NurbsSurface
from app.geometry.spline.skin_distance import SkinDistance


@dataclass(frozen=True)
class FitResult:
    """Everything the pipeline produced (calf-frame mm unless stated)."""

    surface: NurbsSurface
    frame: cf.CalfFrame
    landmarks: Landmarks
    sections: PolarSections  # the resampled sections between B and D
    layer_sections: PolarSections  # the 7 feature layers
    layer_points: np.ndarray  # (7, m, 3) the data grid
    feature_angles_rad: np.ndarray  # (m,)
    error: SurfaceError
    side: str | None
    n_scan_points: int
    options: FitOptions
    timings: dict = field(default_factory=dict)
    placement: LegPlacement | None = None
    lsq: LsqFit | None = None  # mode "lsq": the grid and the correction rounds
    sole_mm: float | None = None  # calf-frame z of the sole (the heel's lowest skin) when the scan has it
    #: why a scan with its foot in it has no sole to measure lengths from (app.geometry.anatomy.sole)
    sole_reason: str | None = None
    skin: SkinDistance | None = None  # surface -> scan distances (app.geometry.spline.skin_distance)
    skin_layers: SkinLayers | None = None  # a cloud's skin, one layer or two (app.geometry.scan.skin_layers)
    #: a cloud's skin stepping along a line up the calf (app.geometry.scan.skin_seam)
    skin_seam: SkinSeam | None = None
    #: a cloud too sparse for thin slabs (SPARSE_CLOUD_POINTS_PER_MM): its points per mm of
    #: the calf's height (the fit warns; a thigh-high designed from it is "review")
    sparse_points_per_mm: float | None = None
    fit_warnings: tuple = ()  # what the fit itself noticed (the surface off the skin, too few points)
    foot: FootMeasures | None = None  # foot length, cA, cY (app.geometry.anatomy.foot) when measured
    thigh: ThighMeasures | None = None  # cE, cF, cG (app.geometry.anatomy.thigh) when measured
    #: the leg's surface from B to G when the scan reaches G (app.geometry.fit.leg_model), or why not
    leg_model: LegModelOutcome | None = None

    @property
    def warnings(self) -> list[str]:
        return (list(self.placement.warnings) if self.placement is not None else []) + list(self.fit_warnings)
