"""Graduated compression stocking design on the NURBS calf (paper section 4, Laplace's law).

The fabric is :mod:`app.geometry.garment.fabric`, the classes and the gradient
:mod:`app.geometry.garment.standards`, the rings and pressures :mod:`app.geometry.garment.pressure`;
this module turns them into a design.

Model
-----
At height h the stretched fabric follows the *convex hull* of the leg's cross-section (it
bridges concavities).  Its length is the hull perimeter L(h).  With tension per unit width
T(h) = K * eps(h), eps = L / L0 - 1 (L0: the relaxed knitted circumference), the local
pressure on the skin is P = T * kappa, kappa the curvature of the contour where the
fabric touches it and 0 where it bridges.  Because the hull of a smooth closed curve turns
by exactly 2*pi along its contact arcs, the mean pressure around the contour is
2*pi*T / L.  kappa comes from the NURBS surface's own derivatives (The NURBS Book eq.
4.20 via :func:`app.geometry.spline.nurbs.evaluate_derivatives`): for the ring C(u) = S(u, v_h)
in the calf's horizontal plane, kappa = (x' y'' - y' x'') / |C'|^3.

Units: lengths mm, tension N/cm (per cm of fabric width; K in N/cm per unit strain),
pressure Pa internally and reported in mmHg (1 mmHg = 133.322 Pa) and kPa.
T [N/cm] * kappa [1/mm] = 1e5 * T * kappa Pa.

Design
------
Targets: a compression class at B (:data:`app.geometry.garment.standards.COMPRESSION_CLASSES`)
graded down the leg by :data:`app.geometry.garment.standards.GRADIENT`, or explicit pressures at
B, B1, C, D; in between, linear in height.
For every height from B to D (every ``step_mm`` and at the landmarks) the tension that
gives the target mean pressure is T = P * L / (2*pi), the strain comes from the fabric
(linear K, or a measured tension-strain table interpolated by PCHIP, monotone), and
L0 = L / (1 + eps) is the knitting specification, rounded to ``resolution_mm``.  The
prediction is then recomputed from the rounded L0, as the knitted stocking would give.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from app.geometry.anatomy.landmarks import LANDMARK_NAMES
from app.geometry.errors import FailureReason, FitFailure
from app.geometry.garment.fabric import Fabric
from app.geometry.garment.pressure import (
    PA_PER_MMHG,
    PA_PER_N_PER_CM_PER_MM,
    find_hot_spots,
    local_pressure_pa,
    mean_pressure_pa,
    sector_means,
    side_directions,
    surface_rings,
)
from app.geometry.garment.standards import (
    COMPRESSION_CLASSES,
    GRADIENT,
    class_target_mmhg,
    gradient_targets,
    normalize_class,
    validate_targets,
)
from app.geometry.spline.nurbs import NurbsSurface

#: Default limit for local pressure hot spots, mmHg.  Partsch et al. (Dermatol Surg 2008;
#: 34:600-609, the consensus on compression pressures) call sub-bandage pressures above
#: 60 mmHg "very strong"; local pressure over tendons and bony prominences beyond that is
#: where the skin-damage risk the paper warns about begins.  Configurable per design.
DEFAULT_HOT_SPOT_MMHG = 60.0
#: the one set of design defaults (the HTTP schema, the CLI and the service read these):
#: RAL-GZ 387 class II (23-32 mmHg at B, the class most prescribed for venous disease),
#: a linear fabric of K = 10 N/cm per unit strain, the knitting specification every 5 mm
#: with the relaxed circumferences to 1 mm
DEFAULT_STANDARD = "RAL"
DEFAULT_CLASS = "II"
DEFAULT_STIFFNESS_N_PER_CM = 10.0
DEFAULT_STEP_MM = 5.0
DEFAULT_RESOLUTION_MM = 1.0


def design_verdict(checks: list[dict], hot_spots: list[dict], limit_mmhg: float) -> dict:
    """The verdict a clinician reads first: "fail" when a normative check of the standard
    fails; "review" when only an advisory check (the commonly cited, not normative,
    gradient rows) fails or local pressure somewhere exceeds the hot-spot limit; "pass"
    only when every check passes and no hot spot is found.  With the reasons, each a
    sentence naming the check or where the hot spot is (height above B, side, peak)."""
    reasons = [f"{c['name']}: fails (normative)" for c in checks if not c["pass"] and c["normative"]]
    verdict = "fail" if reasons else "pass"
    advisory = [f"{c['name']}: outside (advisory)" for c in checks if not c["pass"] and not c["normative"]]
    spots = [f"local pressure {s['peak_mmHg']:.1f} mmHg above the {limit_mmhg:g} mmHg limit at {s['height_mm']:.0f} mm "
             f"above B ({s['from_height_mm']:.0f}-{s['to_height_mm']:.0f} mm), {s['side']}" for s in hot_spots]
    if verdict == "pass" and (advisory or spots):
        verdict = "review"
    return {"verdict": verdict, "verdict_reasons": reasons + advisory + spots}


@dataclass(frozen=True)
class DesignInputs:
    standard: str = DEFAULT_STANDARD
    compression_class: str | None = DEFAULT_CLASS
    targets_mmhg: dict | None = None  # explicit B, B1, C, D; overrides the class
    fabric: Fabric = field(default_factory=lambda: Fabric.linear(DEFAULT_STIFFNESS_N_PER_CM))
    hot_spot_limit_mmhg: float = DEFAULT_HOT_SPOT_MMHG
    step_mm: float = DEFAULT_STEP_MM
    resolution_mm: float = DEFAULT_RESOLUTION_MM
    n_around: int = 360


def design_stocking(surface: NurbsSurface, landmarks: dict, side: str | None, inputs: DesignInputs) -> dict:
    """The stocking design (see module docstring); a JSON-ready dictionary.

    surface: the calf record's surface; landmarks: name -> {"height_mm", ...} for B, B1,
    C, D; side: "left" | "right" | None.  Raises FitFailure (INVALID_TARGET,
    INVALID_FABRIC, UNREACHABLE_PRESSURE) with the reason.
    """
    for name in LANDMARK_NAMES:
        if name not in landmarks:
            raise FitFailure(FailureReason.INVALID_RECORD, f"the record has no landmark {name}; a design needs B, B1, C and D")
    if not (0.5 <= inputs.step_mm <= 50):
        raise FitFailure(FailureReason.INVALID_TARGET, "step_mm must be 0.5-50 mm")
    if not (0.0 < inputs.resolution_mm <= 10):
        raise FitFailure(FailureReason.INVALID_TARGET, "resolution_mm must be in (0, 10] mm")
    if not (5 <= inputs.hot_spot_limit_mmhg <= 300):
        raise FitFailure(FailureReason.INVALID_TARGET, "the hot-spot limit must be 5-300 mmHg")
    inputs.fabric.validate()

    class_info = None
    if inputs.targets_mmhg is not None:
        targets = validate_targets(inputs.targets_mmhg)
    else:
        standard, cls, bounds = normalize_class(inputs.standard, inputs.compression_class or "")
        targets = gradient_targets(class_target_mmhg(bounds))
        class_info = {"standard": standard, "class": cls, "range_mmHg": list(bounds), "source": COMPRESSION_CLASSES[standard]["source"]}

    landmark_z = {name: float(landmarks[name]["height_mm"]) for name in LANDMARK_NAMES}
    z = np.array([landmark_z[n] for n in LANDMARK_NAMES])
    if np.any(np.diff(z) <= 0):
        raise FitFailure(FailureReason.INVALID_RECORD, "landmark heights must rise B < B1 < C < D")
    grid = np.arange(z[0], z[-1] + 1e-9, inputs.step_mm)
    heights = np.unique(np.round(np.concatenate([grid, z]), 6))
    heights = np.clip(heights, z[0], z[-1])
    rings = surface_rings(surface, heights, inputs.n_around)
    target_mmhg = np.interp(heights, z, [targets[n] for n in LANDMARK_NAMES])
    target_pa = target_mmhg * PA_PER_MMHG
    # mean pressure 2 pi T / L  ->  T = P L / (2 pi)
    tension = target_pa * rings.hull_perimeter / (2 * np.pi * PA_PER_N_PER_CM_PER_MM)
    strain = inputs.fabric.strain_for(tension)
    if not np.isfinite(strain).all():
        worst = int(np.nanargmax(np.where(np.isfinite(strain), -np.inf, tension)))
        raise FitFailure(
            FailureReason.UNREACHABLE_PRESSURE,
            f"at {heights[worst]:.0f} mm the target {target_mmhg[worst]:.1f} mmHg needs a tension of "
            f"{tension[worst]:.2f} N/cm, more than the fabric gives within its strain limit "
            f"({inputs.fabric.max_strain:.0%}): the stocking would have to stretch beyond what the fabric "
            "takes without tearing; choose a stiffer fabric or a lower class",
        )
    relaxed = rings.hull_perimeter / (1.0 + strain)
    relaxed_knit = np.round(relaxed / inputs.resolution_mm) * inputs.resolution_mm
    # prediction from the knitted (rounded) specification
    strain_knit = rings.hull_perimeter / relaxed_knit - 1.0
    tension_knit = inputs.fabric.tension(np.maximum(strain_knit, 0.0))
    local = local_pressure_pa(rings, tension_knit)
    mean = mean_pressure_pa(rings, tension_knit)
    directions, side_assumed = side_directions(side)
    sides = sector_means(rings, local, directions)

    index = {name: int(np.argmin(np.abs(heights - landmark_z[name]))) for name in LANDMARK_NAMES}
    per_landmark: dict[str, dict[str, Any]] = {}
    for name in LANDMARK_NAMES:
        i = index[name]
        per_landmark[name] = {
            "height_mm": float(heights[i]),
            "target_mmHg": float(target_mmhg[i]),
            "mean_pressure_mmHg": float(mean[i] / PA_PER_MMHG),
            "mean_pressure_kPa": float(mean[i] / 1000),
            "peak_pressure_mmHg": float(local[i].max() / PA_PER_MMHG),
            "stretched_circumference_mm": float(rings.hull_perimeter[i]),
            "skin_circumference_mm": float(rings.perimeter[i]),
            "relaxed_circumference_mm": float(relaxed_knit[i]),
            "strain": float(strain_knit[i]),
            "tension_N_per_cm": float(tension_knit[i]),
            "sides_mmHg": {k: float(v[i] / PA_PER_MMHG) for k, v in sides.items()},
            "sides_kPa": {k: float(v[i] / 1000) for k, v in sides.items()},
        }
    p = {name: per_landmark[name]["mean_pressure_mmHg"] for name in LANDMARK_NAMES}
    ratios = {f"{n}/B": p[n] / p["B"] for n in ("B1", "C", "D")}
    checks = _checks(p, ratios, class_info)
    hot_spots = find_hot_spots(rings, local, inputs.hot_spot_limit_mmhg * PA_PER_MMHG, directions)
    spec = [
        {
            "height_mm": float(h),
            "target_mmHg": float(t),
            "stretched_circumference_mm": float(L),
            "tension_N_per_cm": float(T),
            "strain": float(e),
            "relaxed_circumference_mm": float(L0),
            "predicted_mean_mmHg": float(m / PA_PER_MMHG),
        }
        for h, t, L, T, e, L0, m in zip(heights, target_mmhg, rings.hull_perimeter, tension_knit, strain_knit, relaxed_knit, mean)
    ]
    return {
        "units": {"length": "mm", "pressure": "mmHg (kPa where named)", "tension": "N/cm"},
        "class": class_info,
        "targets_mmHg": targets,
        "gradient_table": {k: {**v, "range": list(v["range"])} for k, v in GRADIENT.items()},
        "fabric": inputs.fabric.as_dict(),
        "landmarks": per_landmark,
        "ratios": ratios,
        "checks": checks,
        "passed": all(c["pass"] for c in checks if c["normative"]),
        **design_verdict(checks, hot_spots, inputs.hot_spot_limit_mmhg),
        "hot_spot_limit_mmHg": inputs.hot_spot_limit_mmhg,
        "hot_spots": hot_spots,
        "side": side,
        "side_assumed": side_assumed,
        "knitting_spec": spec,
    }


def _checks(p: dict, ratios: dict, class_info: dict | None) -> list[dict]:
    checks = []
    if class_info is not None:
        lo, hi = class_info["range_mmHg"]
        ok = p["B"] >= lo - 1e-9 and (hi is None or p["B"] <= hi + 1e-9)
        label = f"{lo:g}-{hi:g}" if hi is not None else f">= {lo:g}"
        checks.append({"name": f"B in {class_info['standard']} class {class_info['class']} ({label} mmHg)",
                       "value": p["B"], "pass": bool(ok), "normative": True})
    checks.append({"name": "graded B > B1 > C > D", "value": [p[n] for n in LANDMARK_NAMES],
                   "pass": bool(p["B"] > p["B1"] > p["C"] > p["D"]), "normative": True})
    for name, row in GRADIENT.items():
        lo, hi = row["range"]
        value = ratios[f"{name}/B"]
        checks.append({"name": f"{name}/B in {lo:.0%}-{hi:.0%} ({row['source']})", "value": value,
                       "pass": bool(lo - 1e-9 <= value <= hi + 1e-9), "normative": row["normative"]})
    return checks
