"""Measurements on a fitted surface: girths and tape girths at any height, the volume between
heights, the comparison of two records and the statistics of a population.  Units: mm.
"""

from __future__ import annotations

from app.geometry.measures.surface_girths import girths
from app.geometry.measures.volume import volume_between

__all__ = ["girths", "volume_between"]
