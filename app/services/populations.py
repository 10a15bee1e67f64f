"""Populations of calves: POST /populations -> the average calf (stored as a record), the
main modes of variation, girth percentiles at B, B1, C, D.

The statistics are :mod:`app.geometry.measures.population`'s, over lsq nets of one grid.  A
record that is not an lsq record on that grid is refitted on its stored scan (mode lsq,
its side and units) by a fit job - the same jobs, runners, leases and retries as an
upload's, not inside the request (a refit takes about a second; 200 of them would hold
a request for minutes).  While refits are queued or running the answer is
:class:`Refitting` (HTTP 202 with the jobs); the same request made again once they have
succeeded finds their records and makes the population.  A refit whose job failed is
refused with its reason, and so is an imported record (no scan to refit).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from app.db.models import Job
from app.db.repositories import JOB_FAILED, JOB_SUCCEEDED, JobRepository, ScanRepository
from app.errors import Unprocessable, from_fit_failure
from app.geometry.anatomy import LANDMARK_NAMES
from app.geometry.errors import FitFailure
from app.geometry.measures.population import as_right_leg, distinct_net, girth_percentiles, population_of
from app.geometry.measures.surface_girths import girths
from app.geometry.spline.lsq import LsqGrid, surface_from_net
from app.records.codec import SCHEMA_VERSION, CalfRecord, parse_record
from app.services.fitting import DEFAULT_GRID, parse_options
from app.services.records import RecordService

MIN_RECORDS, MAX_RECORDS = 2, 200
#: seconds a client is asked to wait before asking again while refits run (a fit takes
#: about a second on one core; the answer is the same whenever it asks)
REFIT_RETRY_S = 2
#: the status of a refit that waits for room in the clinic's job queue (no job yet)
WAITING = "waiting"


@dataclass(frozen=True)
class Refitting:
    """The population waits for refits: ``refits`` (record id, job id, status) of the
    records being refitted on the ``grid``; ``new_job_ids``: the jobs this request
    queued, to hand to the runner once the transaction has committed."""

    grid: str
    refits: list
    new_job_ids: list = field(default_factory=list)

    def view(self) -> dict:
        return {
            "status": "refitting",
            "grid": self.grid,
            "refits": [{"record_id": r, "job_id": j, "status": status, "links": {"job": f"/api/v1/jobs/{j}"} if j else {}}
                       for r, j, status in self.refits],
            "detail": f"{len(self.refits)} of the records are being refitted in mode lsq on the {self.grid} grid "
                      "from their stored scans; make the same request again when their jobs have succeeded",
            "retry_after_s": REFIT_RETRY_S,
        }


class PopulationService:
    def __init__(self, session, tenant_id: str, store, max_jobs: int = 10):
        self.records = RecordService(session, tenant_id)
        self.scans = ScanRepository(session, tenant_id)
        self.jobs = JobRepository(session, tenant_id)
        self.store = store
        #: the clinic's bound on queued and running jobs (app.services.fair_share): refits
        #: past it wait for a later request
        self.max_jobs = max_jobs

    def create(self, record_ids: list[str], grid: str | None = None) -> dict | Refitting:
        """The population of ``record_ids`` (its view, the average stored as a record), or
        :class:`Refitting` while some of them are being refitted (jobs queued here are
        flushed, not committed: the caller commits, then hands them to the runner)."""
        ids = list(dict.fromkeys(record_ids))
        if not MIN_RECORDS <= len(ids) <= MAX_RECORDS:
            raise Unprocessable(f"a population needs {MIN_RECORDS} to {MAX_RECORDS} distinct records, got {len(ids)}",
                                code="invalid_population")
        rows = [self.records.get(i) for i in ids]
        parsed = [parse_record(row.body) for row in rows]
        target = self._grid(parsed, grid)
        off_grid = [(row, record) for row, record in zip(rows, parsed) if not _on_grid(record, target)]
        refitted, new_jobs = self._refits(off_grid, target)
        pending = [(row.id, job.id, job.status) if isinstance(job, Job) else (row.id, None, WAITING)
                   for row, job in refitted.items() if isinstance(job, Job) or job is None]
        if pending:
            return Refitting(str(target), pending, [job.id for job in new_jobs])
        nets, mirrored, tape = [], [], {name: [] for name in LANDMARK_NAMES}
        heights = {name: [] for name in LANDMARK_NAMES}
        layers = []
        refit_records = {}
        for row, record in zip(rows, parsed):
            if row in refitted:
                refit_row = refitted[row]
                refit_records[row.id] = refit_row.id
                record = parse_record(refit_row.body)
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
            "refitted": list(refit_records),
            "refit_records": refit_records,
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

    def _refits(self, off_grid: list, grid: LsqGrid) -> tuple[dict, list[Job]]:
        """For each (row, record) off the grid: the record row of its succeeded lsq refit,
        its refit job still to run, or None when the clinic's queue has no room for it yet;
        and the jobs queued here (a record without one)."""
        scans = {row.id: self.scans.get(row.scan_id) if row.scan_id else None for row, _ in off_grid}
        jobs = self.jobs.of_scans([scan.id for scan in scans.values() if scan is not None])
        out, new_jobs = {}, []
        room = self.max_jobs - self.jobs.count_active()
        for row, record in off_grid:
            scan = scans[row.id]
            if scan is None or not self.store.exists(scan.sha256):
                raise Unprocessable(
                    f"record {row.id} is not an lsq record on the {grid} grid and has no stored scan to refit it on "
                    "(an imported record): leave it out, or upload its scan with mode=lsq", code="not_lsq")
            options = parse_options(record.side, (record.scan or {}).get("units"), None, "lsq", str(grid))
            refit = self._refit_of(row, options, [j for j in jobs if j.scan_id == scan.id])
            if refit is None and room > len(new_jobs):
                refit = self.jobs.add(scan.id, options, None)
                new_jobs.append(refit)
                jobs.insert(0, refit)  # two records of one scan share its refit
            out[row] = refit  # None: waits for room in the clinic's queue
        return out, new_jobs

    def _refit_of(self, row, options: dict, jobs: list[Job]):
        """The newest job of the scan with these options decides: succeeded - its record;
        failed - refused with its reason; queued or running - wait for it; none (or its
        record deleted since) - None, a new job is needed."""
        for job in jobs:  # newest first
            if job.options != options:
                continue
            if job.status == JOB_SUCCEEDED:
                refit = self.records.records.get(job.record_id) if job.record_id else None
                if refit is None:
                    continue  # the refitted record was deleted since: refit again
                return refit
            if job.status == JOB_FAILED:
                raise Unprocessable(f"record {row.id} could not be refitted in mode lsq (job {job.id}): "
                                    f"{job.error_detail or job.error_code}", code="not_lsq")
            return job
        return None

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
