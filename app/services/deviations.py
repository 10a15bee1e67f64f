"""The scan's points of a record's calf and their distance to its surface: where the
model departs from the scan (the workbench's error-colour map; any client may ask).

The stored scan is read again, taken into the record's calf frame (the inverse of the
record's ``frame``), kept between the surface's end rings and within
:data:`NEAR_MM` of the surface (a body scan's other leg, a floor, stray points are not
this calf), thinned by a fixed stride (before and after), and each point's exact
distance to the surface is computed (Newton foot points, :func:`app.geometry.spline.distance.foot_points`).
"""

from __future__ import annotations

import numpy as np

from app.db.repositories import ScanRepository
from app.errors import NotFound, Unprocessable
from app.geometry.errors import FitFailure
from app.geometry.measures.volume import cut_height_range
from app.geometry.scan.reader import UNIT_SCALE_MM, load_scan
from app.geometry.spline.distance import foot_points
from app.services.records import RecordService, _parse

NEAR_MM = 15.0
MAX_POINTS = 50_000


class DeviationService:
    def __init__(self, session, tenant_id: str, store):
        self.records = RecordService(session, tenant_id)
        self.scans = ScanRepository(session, tenant_id)
        self.store = store

    def scan_points(self, record_id: str, limit: int) -> dict:
        record = self.records.get(record_id)
        scan_row = self.scans.get(record.scan_id) if record.scan_id else None
        if scan_row is None or not self.store.exists(scan_row.sha256):
            raise NotFound(f"record {record_id} has no stored scan (an imported or population record)",
                           code="scan_not_found")
        parsed = _parse(record.body)
        units = (parsed.scan or {}).get("units") or "mm"
        try:
            scan = load_scan(self.store.path_for(scan_row.sha256), file_type=scan_row.file_format, units=units)
        except FitFailure as failure:  # the stored file was accepted once; a changed reader may not
            raise Unprocessable(f"the stored scan cannot be read again: {failure.detail}", code="scan_unreadable") from failure
        frame = np.asarray(parsed.frame)
        in_units = scan.points_mm / UNIT_SCALE_MM[units]
        local = (in_units - frame[:3, 3]) @ np.linalg.inv(frame[:3, :3]).T  # calf frame, mm
        low, high = cut_height_range(parsed.surface)
        local = local[(local[:, 2] >= low) & (local[:, 2] <= high)]
        # thinned before the distances are computed: twice the points asked for leaves
        # room for those that are not this calf (dropped below)
        local = local[:: max(int(np.ceil(len(local) / (2 * limit))), 1)]
        distance, _, _ = foot_points(parsed.surface, local, high - low) if len(local) else (np.zeros(0),) * 3
        near = distance <= NEAR_MM
        local, distance = local[near], distance[near]
        stride = max(int(np.ceil(len(local) / limit)), 1)
        local, distance = local[::stride], distance[::stride]
        return {
            "record_id": record.id,
            "frame": "calf (B at the origin, z up the leg, y anterior), mm",
            "n_points": int(len(local)),
            "points": np.round(local, 3).tolist(),
            "distance_mm": np.round(distance, 4).tolist(),
            "median_distance_mm": float(np.median(distance)) if len(distance) else None,
            "max_distance_mm": float(distance.max()) if len(distance) else None,
        }
