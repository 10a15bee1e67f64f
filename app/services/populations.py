"""Populations of calves: POST /populations -> the average calf (stored as a record), the
main modes of variation, girth percentiles at B, B1, C, D.

The statistics are :mod:`app.geometry.population`'s, over lsq nets of one grid.  A
record that is not an lsq record on that grid is refitted on its stored scan (mode lsq,
its side and units); an imported record has no scan and is refused with the reason.
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from app.db.repositories import ScanRepository
from app.errors import Unprocessable, from_fit_failure
from app.geometry.errors import FitFailure
from app.geometry.landmarks import LANDMARK_NAMES
from app.geometry.lsq import LsqGrid, surface_from_net
from app.geometry.measure import girths
from app.geometry.population import as_right_leg, distinct_net, girth_percentiles, population_of
from app.geometry.record import SCHEMA_VERSION, CalfRecord, parse_record
from app.services.fitting import DEFAULT_GRID, fit_scan_file
from app.services.records import RecordService

MIN_RECORDS, MAX_RECORDS = 2, 200


class PopulationService:
    def __init__(self, session, tenant_id: str, store):
        self.records = RecordService(session, tenant_id)
        self.scans = ScanRepository(session, tenant_id)
        self.store = store

    def create(self, record_ids: list[str], grid: str | None = None) -> dict:
        ids = list(dict.fromkeys(record_ids))
        if not MIN_RECORDS <= len(ids) <= MAX_RECORDS:
            raise Unprocessable(f"a population needs {MIN_RECORDS} to {MAX_RECORDS} distinct records, got {len(ids)}",
                                code="invalid_population")
        rows = [self.records.get(i) for i in ids]
        parsed = [parse_record(row.body) for row in rows]
        target = self._grid(parsed, grid)
        nets, refitted, mirrored, tape = [], [], [], {name: [] for name in LANDMARK_NAMES}
        heights = {name: [] for name in LANDMARK_NAMES}
        layers = []
        for row, record in zip(rows, parsed):
            if not _on_grid(record, target):
                record = self._refit(row, record, target)
                refitted.append(row.id)
            net = distinct_net(record.surface)
            if record.side == "left":
                net = as_right_leg(net)
                mirrored.append(row.id)
            nets.append(net)
            for name in LANDMARK_NAMES:
                mark = record.landmarks[name]
                tape[name].append(mark.get("tape_girth_mm", mark["circumference_mm"]))
                heights[name].append(mark["height_mm"])
            layers.append(record.layers.get("heights_mm") or [])
        model = population_of(np.stack(nets))
        body = self._average_record(model, heights, layers, target, ids, mirrored)
        stored = self.records.add_population_average(body)
        return {
            "record_id": stored.id,
            "n": model.n,
            "grid": str(target),
            "modes": [{"mode": i + 1, "variance_share": float(share), "sd_mm": float(sd)}
                      for i, (share, sd) in enumerate(zip(model.variance_share, model.sd_mm))],
            "girth_percentiles": girth_percentiles({k: np.array(v) for k, v in tape.items()}),
            "refitted": refitted,
            "mirrored": mirrored,
            "links": {"average": f"/api/v1/records/{stored.id}", "surface": f"/api/v1/records/{stored.id}/surface"},
        }

    @staticmethod
    def _grid(parsed: list[CalfRecord], grid: str | None) -> LsqGrid:
        """The grid asked for, else the most common among the lsq records, else 7x15."""
        if grid:
            try:
                return LsqGrid.parse(grid)
            except FitFailure as failure:
                raise from_fit_failure(failure) from failure
        grids = [f"{r.fit['grid']['along']}x{r.fit['grid']['around']}" for r in parsed
                 if r.fit.get("mode") == "lsq" and r.fit.get("grid")]
        return LsqGrid.parse(Counter(grids).most_common(1)[0][0] if grids else DEFAULT_GRID)

    def _refit(self, row, record: CalfRecord, grid: LsqGrid) -> CalfRecord:
        scan = self.scans.get(row.scan_id) if row.scan_id else None
        if scan is None or not self.store.exists(scan.sha256):
            raise Unprocessable(
                f"record {row.id} is not an lsq record on the {grid} grid and has no stored scan to refit it on "
                "(an imported record): leave it out, or upload its scan with mode=lsq", code="not_lsq")
        options = {"side": record.side, "units": (record.scan or {}).get("units"), "mode": "lsq", "grid": str(grid)}
        try:
            fitted = fit_scan_file(str(self.store.path_for(scan.sha256)), scan.file_format, options)
        except FitFailure as failure:
            raise Unprocessable(f"record {row.id} could not be refitted in mode lsq: {failure.detail}",
                                code="not_lsq") from failure
        return parse_record(fitted["record"])

    @staticmethod
    def _average_record(model, heights: dict, layers: list, grid: LsqGrid, ids: list[str], mirrored: list[str]) -> dict:
        surface = surface_from_net(model.mean_net)
        mean_heights = {name: float(np.mean(values)) for name, values in heights.items()}
        measured = girths(surface, np.array([mean_heights[n] for n in LANDMARK_NAMES]))
        landmarks = {name: {"height_mm": mean_heights[name], "circumference_mm": g.circumference_mm,
                            "tape_girth_mm": g.tape_mm} for name, g in zip(LANDMARK_NAMES, measured)}
        complete = [layer for layer in layers if len(layer) == 7]
        record = CalfRecord(
            surface=surface,
            frame=np.eye(4),
            landmarks=landmarks,
            side="right",
            layers={"heights_mm": np.mean(complete, axis=0).tolist() if complete else []},
            fit={"mode": "lsq", "grid": {"along": grid.along, "around": grid.around},
                 "population": {"n": model.n, "record_ids": ids, "mirrored": mirrored}},
            scan={"units": "mm", "format": "population", "n_points": 0, "anterior_cue": "population"},
            schema_version=SCHEMA_VERSION,
            warnings=(f"the average of {model.n} calves" + (f" ({len(mirrored)} left legs mirrored)" if mirrored else ""),),
            side_inference={"side": "right", "confidence": None, "source": "population"},
        )
        return record.to_dict()


def _on_grid(record: CalfRecord, grid: LsqGrid) -> bool:
    fit_grid = record.fit.get("grid") or {}
    return record.fit.get("mode") == "lsq" and (fit_grid.get("along"), fit_grid.get("around")) == (grid.along, grid.around)
