"""Reading a scan and cleaning it: the readers (STL, PLY, OBJ, OFF, glTF/GLB, XYZ/CSV) with their
integrity and size checks, and the clean-up (floor, spikes, stray pieces).  Units: mm.
"""

from __future__ import annotations

from app.geometry.scan.cleanup import CleanScan, clean_scan
from app.geometry.scan.reader import SUPPORTED_FORMATS, UNIT_SCALE_MM, Scan, load_scan

__all__ = ["CleanScan", "SUPPORTED_FORMATS", "Scan", "UNIT_SCALE_MM", "clean_scan", "load_scan"]
