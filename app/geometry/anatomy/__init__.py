"""The anatomy of a calf profile: the landmarks B, B1, C, D (paper section 2.2), the feature
points of the seven layers (section 2.3) and the side of a single leg from its foot.
"""

from __future__ import annotations

from app.geometry.anatomy.feature_layers import LANDMARK_NAMES, Landmark, Landmarks
from app.geometry.anatomy.side import infer_side

__all__ = ["LANDMARK_NAMES", "Landmark", "Landmarks", "infer_side"]
