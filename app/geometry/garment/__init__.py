"""The compression garment: fabrics, the compression classes and gradients of the
standards (RAL-GZ 387, BS 6612, NF G30-102), Laplace pressure P = K eps / r (paper
section 4) and the stocking design with its knitting specification.
"""

from __future__ import annotations

from app.geometry.garment.design import DesignInputs, StockingDesign, design_stocking
from app.geometry.garment.fabric import Fabric
from app.geometry.garment.standards import COMPRESSION_CLASSES, GRADIENT

__all__ = ["COMPRESSION_CLASSES", "DesignInputs", "Fabric", "GRADIENT", "StockingDesign", "design_stocking"]
