"""The leg the upload check cut out, handed to its job's fit: one placement per upload.

The check (:func:`app.services.fitting.validate_scan_file`) reads the scan, cleans it,
finds the leg and places the calf.  It writes the leg it cut out to a file, and the
job's fit (:func:`app.services.fitting.fit_scan_file`) fits that leg instead of reading,
cleaning and splitting the scan again (on the Visible Human scans, half the cost of a
fit's start: the two-leg split and the clean-up's spike and spacing passes).

The file is an uncompressed numpy ``.npz`` read without pickles: ``points`` (n, 3)
float64 scan mm, ``faces`` (f, 3) int64 (absent for a cloud), the scan's point count,
units and format, and the placement's JSON, which must equal the job's: a leg cut for
another placement is not used.

A hand-off, not storage (scans are health data: the leg is kept no longer than its job
waits):

- the fit that reads the file removes it; a retried fit (its first try's process died)
  finds none and reads the scan, as a job without a check's leg does;
- erasing a queued job removes its file (:mod:`app.services.erasure`);
- a check that fails, or a crash before the job is stored, leaves the file beside the
  upload in the temporary folder, removed with it (``ScanStore.clean_temp``).
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from app.geometry.placement import LegPlacement, PlacedLeg
from app.geometry.scan.reader import Scan

FORMAT_VERSION = 1


@dataclass(frozen=True)
class HandedLeg:
    """A placed leg and what the record says of the scan it was cut from."""

    leg: PlacedLeg
    n_scan_points: int
    units: str
    source_format: str


def _placement_json(placement: dict) -> str:
    """The placement as the job stores it (LegPlacement.to_dict, through the database's
    JSON and back), keys sorted: two equal placements give equal text."""
    return json.dumps(placement, sort_keys=True)


def write_placed_leg(path: str | Path, leg: PlacedLeg, scan: Scan) -> None:
    """Write ``leg`` (cut out of ``scan``) for its job's fit."""
    arrays = {"points": np.ascontiguousarray(leg.points, dtype=np.float64)}
    if leg.faces is not None:
        arrays["faces"] = np.ascontiguousarray(leg.faces, dtype=np.int64)
    with open(path, "wb") as handle:
        np.savez(handle, **arrays, version=np.int64(FORMAT_VERSION), n_scan_points=np.int64(len(scan.points_mm)),
                 units=np.str_(scan.units), source_format=np.str_(scan.source_format),
                 placement=np.str_(_placement_json(leg.placement.to_dict())))


def take_placed_leg(path: str | Path, placement: dict) -> HandedLeg | None:
    """The leg written for ``placement`` at ``path``, which is removed; None when there is
    none, or it is unreadable, of another version or cut for another placement (the fit
    then reads the scan)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as stored:
            if int(stored["version"]) != FORMAT_VERSION or str(stored["placement"]) != _placement_json(placement):
                return None
            points = stored["points"]
            faces = stored["faces"] if "faces" in stored.files else None
            handed = HandedLeg(PlacedLeg(points, faces, LegPlacement.from_dict(placement)), int(stored["n_scan_points"]),
                               str(stored["units"]), str(stored["source_format"]))
    except (OSError, KeyError, ValueError, TypeError, zipfile.BadZipFile):
        return None
    finally:
        path.unlink(missing_ok=True)
    if points.ndim != 2 or points.shape[1:] != (3,) or (faces is not None and (faces.ndim != 2 or faces.shape[1:] != (3,))):
        return None
    return handed
