"""The thigh part of a thigh-high (AG) stocking: from D up to G, on the thigh's tape girth
profile measured from the scan (app.geometry.anatomy.thigh).

Model: as below the knee (:mod:`app.geometry.garment.design`), the stretched fabric
follows the convex hull of the section, of length L(h) = the tape girth, and its mean
pressure is P = 2 pi T / L (Laplace's law averaged round the hull, paper section 4).  The
record's NURBS surface ends at D, so above it there is no curvature to map local pressure
and hot spots from: the thigh is designed and checked on its mean pressure only, and the
design says so.

Targets: the pressure at D (the calf part's predicted mean), then the thigh rows of
:data:`app.geometry.garment.standards.THIGH_GRADIENT` at F and G as fractions of B's
target, linear in height in between (E lies between D and F).  Tension T = P L / (2 pi),
strain from the fabric, relaxed L0 = L / (1 + eps) rounded to the resolution, the
prediction recomputed from the rounded L0 - the calf's step
(:func:`app.geometry.garment.knitting.knit_rows`).  Units: mm, Pa internally, mmHg reported, N/cm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.garment.fabric import Fabric
from app.geometry.garment.knitting import KnittingSpec, knit_rows
from app.geometry.garment.pressure import PA_PER_MMHG, laplace_mean_pa
from app.geometry.garment.standards import THIGH_GRADIENT, DesignCheck


@dataclass(frozen=True)
class ThighLevel:
    """The design at E, F or G: height mm, target and predicted mean mmHg, circumferences mm."""

    height_mm: float
    target_mmhg: float
    mean_pressure_mmhg: float
    stretched_circumference_mm: float
    relaxed_circumference_mm: float
    strain: float
    tension_n_per_cm: float


@dataclass(frozen=True)
class ThighPart:
    """The rows from just above D to G (a knitting specification), the levels E, F, G and
    the thigh's checks."""

    rows: KnittingSpec
    levels: dict[str, ThighLevel]
    checks: tuple[DesignCheck, ...]


def thigh_part(profile_heights_mm: np.ndarray, profile_girths_mm: np.ndarray, level_heights_mm: dict[str, float],
               target_b_mmhg: float, pressure_d_mmhg: float, fabric: Fabric, step_mm: float,
               resolution_mm: float) -> ThighPart:
    """The thigh part (module docstring).  profile (k,) heights and tape girths mm from D
    to G; ``level_heights_mm`` E, F, G; B's target and the calf part's predicted mean
    pressure at D, mmHg (the thigh grades on from what the stocking gives at D).  Raises
    FitFailure UNREACHABLE_PRESSURE when the fabric cannot give a target within its
    strain limit (:func:`app.geometry.garment.knitting.knit_rows`)."""
    z_d, z_g = float(profile_heights_mm[0]), float(profile_heights_mm[-1])
    grid = np.arange(z_d + step_mm, z_g + 1e-9, step_mm)
    heights = np.unique(np.round(np.concatenate([grid, [level_heights_mm[n] for n in ("E", "F", "G")]]), 6))
    heights = heights[(heights > z_d + 1e-6) & (heights <= z_g + 1e-6)]  # (rounded to 1e-6 mm above)
    girth = np.interp(heights, profile_heights_mm, profile_girths_mm)
    anchors_z = [z_d, level_heights_mm["F"], level_heights_mm["G"]]
    anchors_p = [pressure_d_mmhg, THIGH_GRADIENT["F"]["target"] * target_b_mmhg, THIGH_GRADIENT["G"]["target"] * target_b_mmhg]
    target = np.interp(heights, anchors_z, anchors_p)
    knitted = knit_rows(heights, target, girth, fabric, resolution_mm, where="on the thigh at")
    mean_pa = laplace_mean_pa(knitted.tension_n_per_cm, girth)
    levels = {}
    for name in ("E", "F", "G"):
        i = int(np.argmin(np.abs(heights - level_heights_mm[name])))
        levels[name] = ThighLevel(float(heights[i]), float(target[i]), float(mean_pa[i] / PA_PER_MMHG), float(girth[i]),
                                  float(knitted.relaxed_mm[i]), float(knitted.strain[i]), float(knitted.tension_n_per_cm[i]))
    rows = KnittingSpec(heights, target, girth, knitted.tension_n_per_cm, knitted.strain, knitted.relaxed_mm, mean_pa)
    return ThighPart(rows, levels, _thigh_checks(levels, target_b_mmhg, pressure_d_mmhg))


def _thigh_checks(levels: dict[str, ThighLevel], target_b: float, pressure_d: float) -> tuple[DesignCheck, ...]:
    p = {name: level.mean_pressure_mmhg for name, level in levels.items()}
    checks = [DesignCheck("graded D > E > F > G", [pressure_d, p["E"], p["F"], p["G"]],
                          bool(pressure_d > p["E"] > p["F"] > p["G"]), True)]
    for name, row in THIGH_GRADIENT.items():
        lo, hi = row["range"]
        ratio = p[name] / target_b
        checks.append(DesignCheck(f"{name} {lo:.0%}-{hi:.0%} of B ({row['source']})", ratio, bool(lo <= ratio <= hi),
                                  row["normative"]))
    return tuple(checks)
