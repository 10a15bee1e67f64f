"""Reading a scan and cleaning it: the readers (STL, PLY, OBJ, OFF, glTF/GLB, XYZ/CSV) with their
integrity and size checks, the clean-up (floor, spikes, stray pieces) and the points' share of
the skin (sampling: statistics over the skin, not over the scanner's sampling).  Units: mm.
"""

from __future__ import annotations

from app.geometry.scan.cleanup import CleanScan, clean_scan
from app.geometry.scan.mesh_parts import used_vertices
from app.geometry.scan.reader import SUPPORTED_FORMATS, UNIT_SCALE_MM, Scan, load_scan
from app.geometry.scan.sampling import area_weights, grouped_weighted_quantiles, weighted_quantile, weighted_quantiles

__all__ = ["CleanScan", "SUPPORTED_FORMATS", "Scan", "UNIT_SCALE_MM", "area_weights", "clean_scan",
           "grouped_weighted_quantiles", "load_scan", "used_vertices", "weighted_quantile", "weighted_quantiles"]
