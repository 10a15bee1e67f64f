"""Knitted fabric: tension per unit width as a function of strain (paper section 4).

A stocking's fabric is either linear - T = K * eps, K in N/cm per unit strain, as the
paper's Laplace model P = K * eps / r takes it - or a measured tension-strain table
(a tensile test of the knit), interpolated by PCHIP (monotone, no overshoot between
rows).  Units: tension N/cm (per cm of fabric width), strain dimensionless.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import PchipInterpolator

from app.geometry.errors import FailureReason, FitFailure

#: strain a plain linear fabric may be asked for (100%); beyond it the design is refused
DEFAULT_MAX_STRAIN = 1.0


@dataclass(frozen=True)
class Fabric:
    """Tension per unit width as a function of strain.

    Either ``stiffness_n_per_cm`` (linear: T = K * eps up to ``max_strain``) or a
    measured table ``strains`` / ``tensions_n_per_cm`` (strictly increasing, starting at
    0 tension at 0 strain is not required), interpolated by PCHIP, valid up to its last
    strain.
    """

    stiffness_n_per_cm: float | None = None
    strains: tuple = ()
    tensions_n_per_cm: tuple = ()
    max_strain: float = DEFAULT_MAX_STRAIN

    @staticmethod
    def linear(stiffness_n_per_cm: float, max_strain: float = DEFAULT_MAX_STRAIN) -> Fabric:
        fabric = Fabric(stiffness_n_per_cm=float(stiffness_n_per_cm), max_strain=float(max_strain))
        fabric.validate()
        return fabric

    @staticmethod
    def table(strains, tensions_n_per_cm) -> Fabric:
        strains = tuple(float(s) for s in strains)
        tensions = tuple(float(t) for t in tensions_n_per_cm)
        fabric = Fabric(strains=strains, tensions_n_per_cm=tensions, max_strain=max(strains) if strains else 0.0)
        fabric.validate()
        return fabric

    def validate(self) -> None:
        if self.stiffness_n_per_cm is not None:
            k = self.stiffness_n_per_cm
            if not np.isfinite(k) or k <= 0:
                raise FitFailure(FailureReason.INVALID_FABRIC, f"stiffness must be a positive number of N/cm, not {k}")
            if k > 1000:
                raise FitFailure(FailureReason.INVALID_FABRIC,
                                 f"a stiffness of {k:g} N/cm per unit strain is not a knitted fabric (expected 0.1-100)")
            if not (0 < self.max_strain <= 5):
                raise FitFailure(FailureReason.INVALID_FABRIC, f"max_strain must be in (0, 5], not {self.max_strain}")
            return
        s, t = np.array(self.strains), np.array(self.tensions_n_per_cm)
        if len(s) < 2 or len(s) != len(t):
            raise FitFailure(FailureReason.INVALID_FABRIC, "a tension-strain table needs at least 2 rows of (strain, tension)")
        if not (np.isfinite(s).all() and np.isfinite(t).all()):
            raise FitFailure(FailureReason.INVALID_FABRIC, "the tension-strain table has non-finite values")
        if (s < 0).any() or (t < 0).any():
            raise FitFailure(FailureReason.INVALID_FABRIC, "strains and tensions must not be negative")
        if np.any(np.diff(s) <= 0) or np.any(np.diff(t) <= 0):
            raise FitFailure(FailureReason.INVALID_FABRIC, "the tension-strain table must be strictly increasing in strain and in tension")
        if s[-1] > 5 or t[-1] > 1000:
            raise FitFailure(FailureReason.INVALID_FABRIC, "the table reaches beyond 500% strain or 1000 N/cm: not a knitted fabric")

    def tension(self, strain: np.ndarray) -> np.ndarray:
        """T(eps), N/cm."""
        strain = np.asarray(strain, dtype=float)
        if self.stiffness_n_per_cm is not None:
            return self.stiffness_n_per_cm * strain
        return PchipInterpolator(self.strains, self.tensions_n_per_cm, extrapolate=True)(strain)

    def strain_for(self, tension: np.ndarray) -> np.ndarray:
        """eps(T), the inverse (monotone, so well defined); NaN beyond the fabric's range."""
        tension = np.asarray(tension, dtype=float)
        if self.stiffness_n_per_cm is not None:
            strain = tension / self.stiffness_n_per_cm
            return np.where(strain <= self.max_strain + 1e-12, strain, np.nan)
        # invert the forward PCHIP itself (monotone): sample it densely and interpolate
        grid = np.linspace(self.strains[0], self.strains[-1], 4001)
        forward = self.tension(grid)
        strain = np.interp(tension, forward, grid, left=np.nan, right=np.nan)
        below = tension < self.tensions_n_per_cm[0]
        if below.any():  # below the first row: linear towards zero strain
            strain = np.where(below, tension / self.tensions_n_per_cm[0] * self.strains[0], strain)
        return strain

    def as_dict(self) -> dict:
        if self.stiffness_n_per_cm is not None:
            return {"stiffness_n_per_cm": self.stiffness_n_per_cm, "max_strain": self.max_strain}
        return {"table": [[s, t] for s, t in zip(self.strains, self.tensions_n_per_cm)]}
