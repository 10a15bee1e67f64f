"""A model of the leg above the calf: a least-squares B-spline surface from B (the ankle's
waist) to G (the top of the thigh) when the scan reaches G - what a thigh-high stocking is
knitted over, and what a manufacturer's CAD reads.  The paper's calf record (B to D, 7
layers, section 2) stays as it is; this surface is the record's second one.

Method: the lsq calf's (:mod:`app.geometry.spline.lsq`), over the whole leg:

- **Axis and sections.**  The calf frame's z (the shank's axis) carried on through the
  knee: on a standing leg the thigh continues it within a few degrees (the femur's 5-9
  degree valgus; :mod:`app.geometry.anatomy.thigh` measures E, F, G in the same planes),
  so the leg is resampled in planes across that axis every :data:`SECTION_STEP_MM` from B
  to G on :data:`N_ANGLES` rays (paper section 2.1's polar resampling).  A bent knee has
  no G (the thigh is cut free of the shank) and so no leg model: the record says why.
- **Anatomical v.**  The seven points of the order form B, B1, C, D, E, F, G sit at v =
  k/6 (PCHIP in height), as the calf's seven layers do: two legs' models correspond
  control point to control point at their anatomy.
- **Net** :data:`GRID` (rows along x columns around): 24 rows over a 550-700 mm leg put a
  knot span every ~30 mm, the knee's and the gluteal fold's curvature resolved; the net
  is fitted to the sections (two small least-squares problems on the section grid, de
  Boor ch. XVII).  Rounds of squared-distance minimization against the scan's points
  (Wang, Pottmann & Liu 2006; :data:`CORRECTIONS`, none by default) were measured on the
  BodyParts3D leg (B to G 617 mm): scan -> surface p95 0.83 mm without a round, 0.42 mm
  with one, 0.35 mm with two, at +0.2 s a round; surface -> scan p99 1.4 / 1.5 / 1.3 mm.
  The sections' fit is within a millimetre of the skin already: a round is not worth
  doubling the fit's time.
- **On the skin**: the surface's distance to the scan (app.geometry.spline.skin_distance)
  sampled every :data:`SKIN_ROW_SPACING_MM`, kept with the model.

Units: mm, calf frame (B at z = 0).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from app.geometry.anatomy.feature_layers import Landmarks
from app.geometry.anatomy.thigh import ThighMeasures
from app.geometry.errors import FitFailure
from app.geometry.sections import slice_polar
from app.geometry.spline.lsq import LsqFit, LsqGrid, fit_lsq_surface
from app.geometry.spline.skin_distance import SkinDistance, surface_to_scan

#: the seven points the model's v is anchored at (v = k/6)
LEG_POINTS = ("B", "B1", "C", "D", "E", "F", "G")
GRID = LsqGrid(along=24, around=24)
SECTION_STEP_MM = 2.0
N_ANGLES = 72
#: no squared-distance round (module docstring): the sections' fit is already within a
#: millimetre of the skin, and a round costs 0.2 s for 0.4 mm of p95
CORRECTIONS = 0
#: the leg's distance to the skin is sampled on rings this far apart (the calf's: 3 mm)
SKIN_ROW_SPACING_MM = 6.0


@dataclass(frozen=True)
class LegModel:
    """The leg's surface from B to G, the heights (7,) of B, B1, C, D, E, F, G it is
    anchored at (mm, calf frame), the lsq fit's record and its distance to the skin."""

    fit: LsqFit
    layer_heights_mm: np.ndarray
    skin: SkinDistance

    def as_dict(self) -> dict:
        """The record's ``leg_model`` apart from its surface and range (the codec writes those)."""
        return {"grid": str(self.fit.grid), "layers_mm": dict(zip(LEG_POINTS, map(float, self.layer_heights_mm))),
                "correction_rms_mm": list(self.fit.rms_mm), "surface_to_scan": self.skin.as_dict()}


@dataclass(frozen=True)
class LegModelOutcome:
    """The leg model, or None with the reason."""

    model: LegModel | None
    reason: str | None = None


def fit_leg_model(points: np.ndarray, faces: np.ndarray | None, layer_heights_mm: np.ndarray) -> LegModelOutcome:
    """The leg model (module docstring) of the placed leg: points (n, 3) calf-frame mm,
    faces (f, 3) or None; layer_heights_mm (7,) rising: B, B1, C, D, E, F, G."""
    layers = np.asarray(layer_heights_mm, dtype=np.float64)
    if layers.shape != (7,) or not np.all(np.diff(layers) > 0):
        return LegModelOutcome(None, "the leg model needs B, B1, C, D, E, F and G rising up the leg")
    heights = np.unique(np.r_[np.arange(layers[0], layers[-1], SECTION_STEP_MM), layers[-1]])
    sections = slice_polar(points, faces, heights, N_ANGLES)
    if sections.valid.mean() < 0.5:
        return LegModelOutcome(None, f"only {sections.valid.mean():.0%} of the leg's sections from B to G are closed "
                                     "(holes or crops): too few to model it")
    inside = points[(points[:, 2] >= layers[0]) & (points[:, 2] <= layers[-1])]
    try:
        fit = fit_lsq_surface(sections, layers, inside, GRID, corrections=CORRECTIONS)
    except FitFailure as failure:  # the calf's record stands without it
        return LegModelOutcome(None, f"the leg's surface could not be fitted: {failure.detail}")
    # the border curves of the clamped surface are its first and last control rows: held
    # in the planes of B and G exactly (the sections' fit leaves them ~0.002 mm off), as
    # the lsq calf's are
    control = fit.surface.control_points.copy()
    control[:, 0, 2], control[:, -1, 2] = layers[0], layers[-1]
    fit = dataclasses.replace(fit, surface=dataclasses.replace(fit.surface, control_points=control))
    skin = surface_to_scan(fit.surface, points, faces, layers[0], layers[-1], SKIN_ROW_SPACING_MM)
    return LegModelOutcome(LegModel(fit, layers, skin))


def leg_model_of(points: np.ndarray, faces: np.ndarray | None, landmarks: Landmarks,
                 thigh: ThighMeasures | None) -> LegModelOutcome:
    """The leg model from B to G (:func:`fit_leg_model`) when the thigh's points were
    measured (landmarks B, B1, C, D of the calf; E, F, G of the thigh), else why not."""
    if thigh is None or thigh.top_of_thigh.height_mm is None or thigh.knee.height_mm is None \
            or thigh.mid_thigh.height_mm is None:
        reason = "the thigh is not measured" if thigh is None else (
            thigh.top_of_thigh.reason or thigh.mid_thigh.reason or thigh.knee.reason or "E, F or G is not measured")
        return LegModelOutcome(None, reason)
    heights = [landmarks.B.height_mm, landmarks.B1.height_mm, landmarks.C.height_mm, landmarks.D.height_mm,
               thigh.knee.height_mm, thigh.mid_thigh.height_mm, thigh.top_of_thigh.height_mm]
    return fit_leg_model(points, faces, np.array(heights, dtype=np.float64))

