"""A leg's placement as plain data (:class:`LegPlacement`), handed from the upload check
to the fit (serialised once, at the service's edge: :meth:`LegPlacement.to_dict`), and
the leg it cuts out of its scan (:class:`PlacedLeg`).  Found by
:func:`app.geometry.placement.place.place_leg`.  Units: scan mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from app.geometry.placement import calf_frame as cf
from app.geometry.placement.caps import Cap, leave_out_caps
from app.geometry.placement.leg_axis import clip_to_half_spaces
from app.geometry.scan.cleanup import CleanupReplay


@dataclass(frozen=True)
class LegPlacement:
    """Where the calf is in a scan: JSON-ready, to hand from the upload check to the fit.

    rotation (3, 3) rows x, y (anterior), z (up) in scan mm; origin_mm (3,) at B;
    c_mm, d_mm heights of C and D above B; the edge flags; the side and where it came
    from (``given``, ``body`` - from the other leg -, ``foot``, or None) with a
    confidence in [0.5, 1]; ``piece`` and ``half`` say which cleaned piece and which
    leg of it; ``warnings`` in words.
    """

    rotation: np.ndarray
    origin_mm: np.ndarray
    mm_per_unit: float
    anterior_cue: str
    c_mm: float
    d_mm: float
    d_at_window_edge: bool = False
    b_at_scan_edge: bool = False
    d_at_scan_edge: bool = False
    side: str | None = None
    side_source: str | None = None
    side_confidence: float | None = None
    piece: int = 0
    half: int = -1
    warnings: tuple = ()
    #: a bent knee's cut: ((point (3,), normal (3,)), ...) in scan mm, keep (p - point) . normal <= 0
    half_spaces: tuple = ()
    #: the caps a mesh tool closed the scan's cut ends with, left out
    #: (:mod:`app.geometry.placement.caps`)
    caps: tuple[Cap, ...] = ()
    #: what the clean-up found (floor planes, a cloud's voxel size and point spacing): the
    #: fit repeats the clean-up from it; None in a placement stored before it was kept
    #: (the clean-up is then searched for again, with the same result)
    cleanup: CleanupReplay | None = None

    @property
    def frame(self) -> cf.CalfFrame:
        return cf.CalfFrame(self.rotation, self.origin_mm, self.mm_per_unit, self.anterior_cue)

    def cut_out(self, points: np.ndarray, faces: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
        """The leg of the candidate ``points`` (n, 3) and ``faces`` it was placed on: its
        caps left out, a bent knee's thigh cut off."""
        return clip_to_half_spaces(*leave_out_caps(points, faces, self.caps), self.half_spaces)

    def to_dict(self) -> dict:
        return {
            "rotation": np.asarray(self.rotation).tolist(), "origin_mm": np.asarray(self.origin_mm).tolist(),
            "mm_per_unit": self.mm_per_unit, "anterior_cue": self.anterior_cue,
            "c_mm": self.c_mm, "d_mm": self.d_mm, "d_at_window_edge": self.d_at_window_edge,
            "b_at_scan_edge": self.b_at_scan_edge, "d_at_scan_edge": self.d_at_scan_edge,
            "side": self.side, "side_source": self.side_source, "side_confidence": self.side_confidence,
            "piece": self.piece, "half": self.half, "warnings": list(self.warnings),
            "half_spaces": [[np.asarray(p).tolist(), np.asarray(n).tolist()] for p, n in self.half_spaces],
            "caps": [{"point": np.asarray(c.point).tolist(), "normal": np.asarray(c.normal).tolist(),
                      "depth_mm": c.depth_mm, "flat": c.flat} for c in self.caps],
            **(self.cleanup.to_dict() if self.cleanup is not None else {}),
        }

    @classmethod
    def from_dict(cls, data: dict) -> LegPlacement:
        return cls(
            rotation=np.asarray(data["rotation"], dtype=float), origin_mm=np.asarray(data["origin_mm"], dtype=float),
            mm_per_unit=float(data["mm_per_unit"]), anterior_cue=str(data["anterior_cue"]),
            c_mm=float(data["c_mm"]), d_mm=float(data["d_mm"]),
            d_at_window_edge=bool(data.get("d_at_window_edge", False)),
            b_at_scan_edge=bool(data.get("b_at_scan_edge", False)), d_at_scan_edge=bool(data.get("d_at_scan_edge", False)),
            side=data.get("side"), side_source=data.get("side_source"), side_confidence=data.get("side_confidence"),
            piece=int(data.get("piece", 0)), half=int(data.get("half", -1)), warnings=tuple(data.get("warnings", ())),
            half_spaces=tuple((np.asarray(p, dtype=float), np.asarray(n, dtype=float))
                              for p, n in data.get("half_spaces", ())),
            caps=tuple(Cap(np.asarray(c["point"], dtype=float), np.asarray(c["normal"], dtype=float),
                           float(c["depth_mm"]), bool(c.get("flat", False))) for c in data.get("caps", ())),
            cleanup=CleanupReplay.from_dict(data),
        )


@dataclass(frozen=True)
class PlacedLeg:
    """A leg cut out of its scan (scan mm: points (n, 3), faces (f, 3) or None) and its
    placement."""

    points: np.ndarray
    faces: np.ndarray | None
    placement: LegPlacement
