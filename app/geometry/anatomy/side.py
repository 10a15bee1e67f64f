"""Left or right from the foot of a single-leg scan (anatomy, not a trained model).

In the calf frame (mm; z up the leg from B, y anterior - found from the foot -, x the
subject's right) a right foot and a left foot are mirror images across x = 0, so any
medial-lateral asymmetry of the foot tells them apart.  The one used: the forefoot's
leading edge runs obliquely - the hallux (medial) reaches furthest forward and the toe
line falls back towards the fifth toe (lateral) - so the front of the foot lies medial of
the foot's mid-line.  The statistic is

    s = (x of the front-most 10% of the foot - x of the mid-foot) / foot breadth

s < 0 (front medial = towards -x, the subject's left) for a right foot, s > 0 for a
left one.  Its quantiles are the skin's (each point weighted by its share of the skin's
area, app.geometry.scan.sampling): a cloud sampled 4 times sparser on one side moved the
points' own medians to the dense side and, with the frame that the points' mean foot
turned (app.geometry.placement.calf_frame.anterior_from_foot), read s 0.23 the wrong
way.  The confidence is a logistic of |s| against the spread of s measured on
generated legs (``benchmarks/robustness.py`` reports it); below 0.75 - about one
spread from zero - the side is not reported (null).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.scan.sampling import area_weights, weighted_quantiles

#: the foot is the part of the scan this far below B, mm (B lies ~50-80 mm above the sole)
FOOT_BELOW_B_MM = 30.0
#: front of the foot: the front-most fraction of its length
FRONT_FRACTION = 0.10
#: spread of the statistic s across generated feet (SIDE_SCALE) and the confidence below
#: which no side is reported
SIDE_SCALE = 0.04
MIN_CONFIDENCE = 0.75


def outer_side_angle(side: str | None) -> float | None:
    """The calf frame's angle (radians, from +x towards +y) of the leg's outer (lateral)
    side: x is the subject's right, so 0 for a right leg and pi for a left one; None
    where the side is not known."""
    return {"right": 0.0, "left": float(np.pi)}.get(side or "")


@dataclass(frozen=True)
class SideGuess:
    """``side`` "left" / "right" or None, ``confidence`` in [0.5, 1] or None, the
    statistic ``s`` and, when None, the ``reason`` in words."""

    side: str | None
    confidence: float | None
    statistic: float | None = None
    reason: str | None = None


def foot_asymmetry(calf_points: np.ndarray) -> float | None:
    """The statistic s of the module docstring, or None without a foot.

    calf_points (n, 3) calf-frame mm with B at z = 0.
    """
    foot = calf_points[calf_points[:, 2] < -FOOT_BELOW_B_MM]
    if len(foot) < 200:
        return None
    weight = area_weights(foot)  # quantiles of the skin, not of the scanner's sampling
    y = foot[:, 1]
    lo, hi = weighted_quantiles(y, weight, (0.01, 0.995))
    length = hi - lo
    if length < 100.0:  # a foot is 200-300 mm long; under 100 mm there is no forefoot
        return None
    front = y >= hi - FRONT_FRACTION * length
    middle = (y >= lo + 0.3 * length) & (y <= lo + 0.7 * length)
    if front.sum() < 20 or middle.sum() < 20:
        return None
    x = foot[:, 0]
    side_low, side_high, mid_line = weighted_quantiles(x[middle], weight[middle], (0.02, 0.98, 0.5))
    breadth = side_high - side_low
    if breadth < 40.0:
        return None
    return float((weighted_quantiles(x[front], weight[front], 0.5)[0] - mid_line) / breadth)


def infer_side(calf_points: np.ndarray, anterior_cue: str) -> SideGuess:
    """Left or right of a single leg from its foot (module docstring)."""
    if anterior_cue != "foot":
        return SideGuess(None, None, None, "the foot is not in the scan")
    s = foot_asymmetry(calf_points)
    if s is None:
        return SideGuess(None, None, None, "the foot in the scan is too small to read")
    confidence = float(1.0 / (1.0 + np.exp(-abs(s) / SIDE_SCALE * 2.0)))
    side = "right" if s < 0 else "left"
    if confidence < MIN_CONFIDENCE:
        return SideGuess(None, confidence, s, f"the foot is nearly symmetric (confidence {confidence:.2f})")
    return SideGuess(side, confidence, s)
