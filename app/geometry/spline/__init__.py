"""The NURBS surface (The NURBS Book), its least-squares fit to a scan, the distance from the
surface back to the scan, and the bounds of the surfaces the service evaluates.  Units: mm.
"""

from __future__ import annotations

from app.geometry.spline.lsq import LsqGrid, fit_lsq_surface
from app.geometry.spline.nurbs import NurbsSurface, surface_from_layers

__all__ = ["LsqGrid", "NurbsSurface", "fit_lsq_surface", "surface_from_layers"]
