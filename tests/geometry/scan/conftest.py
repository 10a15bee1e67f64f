"""Shared by the scan checks' tests: a cloud fitted as an upload is, recorded and designed
from, to see what the fit, the record and the design say about it."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import trimesh

from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan
from app.geometry.fit.result import FitResult
from app.geometry.garment.design import DesignInputs, design_stocking
from app.geometry.garment.fabric import Fabric
from app.geometry.scan.reader import load_scan
from app.records.codec import CalfRecord, record_from_fit


@dataclass(frozen=True)
class CloudVerdict:
    """What a cloud's fit warns, its record keeps and a class II design from it says."""

    fit: FitResult
    record: CalfRecord
    verdict: str
    reasons: tuple[str, ...]


@pytest.fixture
def cloud_verdict(tmp_path: Path) -> Callable[[np.ndarray, str], CloudVerdict]:
    """``cloud_verdict(points (n, 3) mm, name)``: the cloud written as a PLY file, checked
    and fitted as an upload is, recorded, and designed from (class II, a linear fabric)."""

    def read(points: np.ndarray, name: str) -> CloudVerdict:
        path = tmp_path / f"{name}.ply"
        trimesh.PointCloud(points).export(path)
        scan = load_scan(path)
        fit = fit_scan(scan, placement=check_scan(scan, FitOptions()))
        record = record_from_fit(fit, scan.source_format, scan.units)
        design = design_stocking(record.surface, record.landmarks, "right",
                                 DesignInputs(compression_class="II", fabric=Fabric.linear(10.0)), record.chart,
                                 record.fit)
        verdict, reasons = design.verdict
        return CloudVerdict(fit, record, verdict, tuple(reasons))

    return read
