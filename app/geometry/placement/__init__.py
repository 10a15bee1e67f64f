"""Placing the leg of a scan: which piece or half of a body is the leg, its axis through the
calf, a bent knee, its side and its size in the unit read.
"""

from __future__ import annotations

from app.geometry.placement.calf_frame import CalfFrame
from app.geometry.placement.leg_placement import LegPlacement, PlacedLeg
from app.geometry.placement.place import place_leg, replace_leg

__all__ = ["CalfFrame", "LegPlacement", "PlacedLeg", "place_leg", "replace_leg"]
