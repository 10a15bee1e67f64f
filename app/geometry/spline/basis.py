"""One direction of a tensor-product B-spline: its knots, degree and form, checked once.

A :class:`BSplineBasis` is the contract every surface of the service keeps (as splipy's
``BSplineBasis`` states its own): a non-decreasing knot vector of n + p + 1 entries with
a non-empty domain ``[knots[p], knots[n]]`` and no interior knot repeated more than p
times (the surface is continuous); ``periodic``: the knot spacings repeat with the
period and the first p control points repeat at the end (the unwrapped form that any
non-periodic NURBS code reads, The NURBS Book section 12.2); otherwise clamped (p + 1
equal knots at each end: the surface's ends are its first and last control rows).

The basis functions themselves are scipy's (de Boor's recurrence, The NURBS Book A2.2):
:meth:`BSplineBasis.local` gives the lsq collocation its rows from
``BSpline.design_matrix``; surfaces are evaluated with ``BSpline`` and
``NdBSpline`` (:mod:`app.geometry.spline.nurbs`).  There is no hand-written basis in the
project.  Parameters are
dimensionless; nothing here has units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.sparse import csr_matrix


@dataclass(frozen=True)
class BSplineBasis:
    """knots (n + degree + 1,) float64; ``degree`` >= 1; ``periodic`` (see the module).

    Raises ValueError, naming the broken rule, when the knots break the contract.
    """

    knots: np.ndarray
    degree: int
    periodic: bool = False

    def __post_init__(self) -> None:
        knots = np.asarray(self.knots, dtype=np.float64)
        object.__setattr__(self, "knots", knots)
        p = self.degree
        if p < 1:
            raise ValueError(f"the degree must be at least 1, not {p}")
        if knots.ndim != 1 or len(knots) < 2 * p + 2:
            raise ValueError(f"a degree-{p} basis needs at least {2 * p + 2} knots, got {knots.size}")
        if not np.isfinite(knots).all():
            raise ValueError("the knots must be finite")
        if np.any(np.diff(knots) < 0):
            raise ValueError("the knots must be non-decreasing")
        n = self.n_functions
        if knots[n] <= knots[p]:
            raise ValueError("the knots leave an empty domain")
        interior = knots[p + 1 : n]
        if interior.size and np.unique(interior, return_counts=True)[1].max() > p:
            raise ValueError(f"an interior knot repeats more than {p} times (the surface would break there)")
        scale = max(1.0, float(np.abs(knots).max()))
        if self.periodic:
            spacing = np.diff(knots)
            period = n - p
            if not np.allclose(spacing[period:], spacing[: len(spacing) - period], rtol=0.0, atol=1e-9 * scale):
                raise ValueError(f"a periodic basis's knot spacings must repeat every {period} knots")
        elif not (np.all(knots[: p + 1] == knots[0]) and np.all(knots[n:] == knots[-1])):
            raise ValueError(f"a clamped basis needs {p + 1} equal knots at each end")

    @property
    def n_functions(self) -> int:
        """n: the number of basis functions (control points in this direction)."""
        return len(self.knots) - self.degree - 1

    @property
    def domain(self) -> tuple[float, float]:
        """``[knots[p], knots[n]]``: where the surface is defined."""
        return float(self.knots[self.degree]), float(self.knots[self.n_functions])

    def design_matrix(self, u: np.ndarray) -> csr_matrix:
        """(N, n) sparse matrix of the basis functions at u (N,), each row holding its
        degree + 1 non-zero values; the domain's right end belongs to the last span, and
        a u outside the domain takes the polynomials of the span at that end."""
        return BSpline.design_matrix(np.asarray(u, dtype=np.float64), self.knots, self.degree, extrapolate=True)

    def local(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Column indices (N, degree + 1) and values (N, degree + 1) of the non-zero
        basis functions at u (N,) (the design matrix's rows, in column order)."""
        design = self.design_matrix(u)
        return design.indices.reshape(-1, self.degree + 1), design.data.reshape(-1, self.degree + 1)
