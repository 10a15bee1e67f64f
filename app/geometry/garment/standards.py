"""Compression classes and the pressure gradient down the leg (RAL-GZ 387, BS 6612,
NF G30-102), with the standing of each row; design targets from them.

Pressures in mmHg; the landmarks B, B1, C, D of :mod:`app.geometry.anatomy.feature_layers`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypedDict

import numpy as np

from app.geometry.anatomy.feature_layers import LANDMARK_NAMES
from app.geometry.errors import FailureReason, FitFailure


@dataclass(frozen=True)
class DesignCheck:
    """One check of a design: its name (with the standard it comes from), the value
    checked (mmHg or a ratio; a list for the gradient), whether it passed and whether
    the standard makes it normative."""

    name: str
    value: float | list[float]
    passed: bool
    normative: bool



class CompressionStandard(TypedDict):
    """A standard's compression classes: name -> (lowest, highest or None) mmHg at B."""

    source: str
    classes: dict[str, tuple[float, float | None]]


class GradientRow(TypedDict):
    """A landmark's pressure as a fraction of B's: allowed range, design target, and
    whether the standard requires it."""

    range: tuple[float, float]
    target: float
    normative: bool
    source: str


#: Compression classes: mean pressure at B (the ankle), mmHg.  None: no upper bound.
COMPRESSION_CLASSES: dict[str, CompressionStandard] = {
    "RAL": {
        "source": "RAL-GZ 387/1 (Germany, 2008): pressure at B",
        "classes": {"I": (18.0, 21.0), "II": (23.0, 32.0), "III": (34.0, 46.0), "IV": (49.0, None)},
    },
    "BS": {
        "source": "BS 6612:1985 (United Kingdom): pressure at the ankle",
        "classes": {"1": (14.0, 17.0), "2": (18.0, 24.0), "3": (25.0, 35.0)},
    },
    "AFNOR": {
        "source": "NF G30-102 (France): pressure at the ankle",
        "classes": {"1": (10.0, 15.0), "2": (15.1, 20.0), "3": (20.1, 36.0), "4": (36.1, None)},
    },
}
#: design target inside a class: the middle of the range; open-ended classes 10% above the bound
OPEN_CLASS_MARGIN = 1.10

#: Pressure gradient down the leg as fractions of the pressure at B.  ONE table, with the
#: standing of each row: only the D row is normative (RAL-GZ 387: at most 70% at D); the
#: B1 and C rows are the values commonly cited in the compression literature and by
#: manufacturers, not a requirement of RAL-GZ 387 - they are marked as such.
GRADIENT: dict[str, GradientRow] = {
    "B1": {"range": (0.70, 1.00), "target": 0.85, "normative": False,
           "source": "commonly cited (not normative in RAL-GZ 387): B1 70-100% of B"},
    "C": {"range": (0.50, 0.80), "target": 0.65, "normative": False,
          "source": "commonly cited (not normative in RAL-GZ 387): C 50-80% of B"},
    "D": {"range": (0.0, 0.70), "target": 0.50, "normative": True,
          "source": "RAL-GZ 387: at D at most 70% of the pressure at B"},
}

#: The thigh of a thigh-high (AG) stocking, as fractions of the pressure at B: the values
#: manufacturers and the compression literature commonly cite for RAL-GZ 387 profiles (F
#: 30-60%, G 20-40% of B); they are not confirmed here as normative text of the standard,
#: so they are advisory (a design outside them is "review", never "fail").  The graduation
#: itself (pressure falling from D to G) is checked as normative, as below the knee.
THIGH_GRADIENT: dict[str, GradientRow] = {
    "F": {"range": (0.30, 0.60), "target": 0.40, "normative": False,
          "source": "commonly cited (not confirmed normative): F 30-60% of B"},
    "G": {"range": (0.20, 0.40), "target": 0.30, "normative": False,
          "source": "commonly cited (not confirmed normative): G 20-40% of B"},
}


def normalize_class(standard: str, name: str) -> tuple[str, str, tuple]:
    """('RAL', 'II', (23, 32)) from loose spellings: 'ral', 'ccl2', '2', 'II'."""
    key = standard.strip().upper()
    if key not in COMPRESSION_CLASSES:
        raise FitFailure(FailureReason.INVALID_TARGET, f"standard must be one of {', '.join(COMPRESSION_CLASSES)}, not {standard!r}")
    classes = COMPRESSION_CLASSES[key]["classes"]
    raw = str(name).strip().upper().replace("CCL", "").replace("CLASS", "").strip()
    roman = {"1": "I", "2": "II", "3": "III", "4": "IV"}
    arabic = {v: k for k, v in roman.items()}
    for candidate in (raw, roman.get(raw, ""), arabic.get(raw, "")):
        if candidate in classes:
            return key, candidate, classes[candidate]
    raise FitFailure(
        FailureReason.INVALID_TARGET, f"{key} has classes {', '.join(classes)}; {name!r} is not one of them"
    )


def class_target_mmhg(bounds: tuple) -> float:
    lo, hi = bounds
    return lo * OPEN_CLASS_MARGIN if hi is None else (lo + hi) / 2


def gradient_targets(at_b_mmhg: float) -> dict:
    return {"B": at_b_mmhg, **{name: row["target"] * at_b_mmhg for name, row in GRADIENT.items()}}


def validate_targets(targets: dict) -> dict:
    clean = {}
    for name in LANDMARK_NAMES:
        if name not in targets:
            raise FitFailure(FailureReason.INVALID_TARGET, f"explicit targets need B, B1, C and D; {name} is missing")
        value = float(targets[name])
        if not np.isfinite(value) or value <= 0:
            raise FitFailure(FailureReason.INVALID_TARGET, f"the target at {name} must be a positive pressure, not {value}")
        if value > 100:
            raise FitFailure(FailureReason.INVALID_TARGET, f"{value:g} mmHg at {name} is beyond any compression class (max 100)")
        clean[name] = value
    return clean
