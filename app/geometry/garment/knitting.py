"""The knitting specification: from a target mean pressure on a stretched circumference
to the relaxed circumference to knit, and the pressure the knitted row then gives
(Laplace's law averaged round the convex hull, paper section 4: P = 2 pi T / L).

One step for the calf (:mod:`app.geometry.garment.design`) and the thigh
(:mod:`app.geometry.garment.thigh_design`).  Units: mm, mmHg in, Pa out, N/cm.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.garment.fabric import Fabric
from app.geometry.garment.pressure import PA_PER_MMHG, PA_PER_N_PER_CM_PER_MM


@dataclass(frozen=True)
class KnittingSpec:
    """The knitting specification, one row per height: all arrays (k,), heights mm,
    target mmHg, predicted mean Pa, stretched and relaxed circumferences mm, tension N/cm,
    strain (-)."""

    heights_mm: np.ndarray
    target_mmhg: np.ndarray
    stretched_circumference_mm: np.ndarray
    tension_n_per_cm: np.ndarray
    strain: np.ndarray
    relaxed_circumference_mm: np.ndarray
    predicted_mean_pa: np.ndarray

    def joined(self, above: KnittingSpec) -> KnittingSpec:
        """This specification followed by the rows of ``above`` (higher up the leg)."""
        return KnittingSpec(*(np.concatenate([getattr(self, f.name), getattr(above, f.name)]) for f in fields(self)))


@dataclass(frozen=True)
class KnittedRows:
    """Rows knitted to their targets: relaxed circumference L0 mm (rounded), and what the
    knitted rows give: strain (-), tension N/cm."""

    relaxed_mm: np.ndarray
    strain: np.ndarray
    tension_n_per_cm: np.ndarray


def knit_rows(heights_mm: np.ndarray, target_mmhg: np.ndarray, stretched_mm: np.ndarray, fabric: Fabric,
              resolution_mm: float, where: str = "at") -> KnittedRows:
    """Knit each row (k,) to its target mean pressure: T = P L / (2 pi), the strain from
    the fabric, L0 = L / (1 + eps) rounded to ``resolution_mm``, then the strain and
    tension of the rounded L0, as the knitted stocking gives them.  Raises FitFailure
    UNREACHABLE_PRESSURE naming the row (``where``: "at", "on the thigh at") whose
    tension the fabric cannot give within its strain limit."""
    tension = target_mmhg * PA_PER_MMHG * stretched_mm / (2 * np.pi * PA_PER_N_PER_CM_PER_MM)
    strain = fabric.strain_for(tension)
    if not np.isfinite(strain).all():
        worst = int(np.nanargmax(np.where(np.isfinite(strain), -np.inf, tension)))
        raise FitFailure(
            FailureReason.UNREACHABLE_PRESSURE,
            f"{where} {heights_mm[worst]:.0f} mm the target {target_mmhg[worst]:.1f} mmHg needs a tension of "
            f"{tension[worst]:.2f} N/cm, more than the fabric gives within its strain limit "
            f"({fabric.max_strain:.0%}): the stocking would have to stretch beyond what the fabric "
            "takes without tearing; choose a stiffer fabric or a lower class",
        )
    relaxed = np.round(stretched_mm / (1.0 + strain) / resolution_mm) * resolution_mm
    strain_knit = stretched_mm / relaxed - 1.0
    return KnittedRows(relaxed, strain_knit, fabric.tension(np.maximum(strain_knit, 0.0)))

