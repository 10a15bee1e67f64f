"""How far a leg's first axis lies from its shank: least squares through the compact slabs'
centroids against their consensus line (app.geometry.placement.first_axis), on every
``step``-th case of the robustness corpus.

The shank's axis is the generator's truth: the line from B's section centroid to D's,
mapped into the scan's millimetres.  Run: ``.venv/bin/python benchmarks/first_axis.py 13 4``
(seed, step); writes benchmarks/results/first_axis.md.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.geometry.placement import calf_frame as cf  # noqa: E402
from app.geometry.placement.first_axis import first_axis, pca_samples  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from benchmarks.corpus.cases import build_case, corpus_specs  # noqa: E402
from benchmarks.provenance import environment, environment_line  # noqa: E402

#: kinds with more than one leg or no shank to measure against
SKIPPED = ("two_legs", "two_legs_no_side", "body_vertices", "coarse_mesh", "fragment")


def _scan_mm(to_scan: np.ndarray, mm_per_unit: float, point: np.ndarray) -> np.ndarray:
    """A generating-frame point (3,) in the scan's millimetres (3,)."""
    return (to_scan @ np.r_[point, 1.0])[:3] * mm_per_unit


def degrees_off(axis: np.ndarray, shank: np.ndarray) -> float:
    return float(np.degrees(np.arccos(min(1.0, abs(float(axis @ shank))))))


def main(seed: int = 13, step: int = 4) -> list[dict]:
    rows = []
    for spec in corpus_specs(220, seed)[::step]:
        if spec.kind in SKIPPED:
            continue
        case = build_case(spec)
        if "D" not in case.truth.points_mm:
            continue
        scan = load_scan(case.data, file_type=case.file_type, units=case.units)
        b, d = (_scan_mm(case.to_scan, scan.mm_per_unit, case.truth.points_mm[name]) for name in ("B", "D"))
        shank = (d - b) / np.linalg.norm(d - b)
        samples, weights = pca_samples(scan.points_mm, scan.faces)
        shape_axes = cf.principal_frame(samples, weights)
        row = {"case": spec.case_id, "kind": spec.kind, "pca_deg": degrees_off(shape_axes[2], shank)}
        for name, consensus in (("least_squares", False), ("consensus", True)):
            started = time.perf_counter()
            axis, _ = first_axis(samples, weights, shape_axes, None, consensus=consensus)
            row[f"{name}_ms"] = 1000 * (time.perf_counter() - started)
            row[f"{name}_deg"] = degrees_off(axis, shank)
        print(f"{spec.case_id:26s} PCA {row['pca_deg']:5.1f}  least squares {row['least_squares_deg']:5.1f}  "
              f"consensus {row['consensus_deg']:5.1f} degrees", flush=True)
        rows.append(row)
    write(rows, seed, step)
    return rows


def write(rows: list[dict], seed: int, step: int) -> None:
    def stats(key: str) -> str:
        a = np.array([r[key] for r in rows])
        return f"{np.median(a):.1f} / {np.percentile(a, 95):.1f} / {a.max():.1f}"

    lines = [f"# A leg's first axis against its shank (robustness corpus 220, seed {seed}, every {step}th case)", "",
             f"`.venv/bin/python benchmarks/first_axis.py {seed} {step}`; {len(rows)} single-leg cases.", "",
             environment_line(environment()), "",
             "Degrees between each axis and the generator's shank (B's to D's section centroid). The placement "
             "reads the leg along least squares first, and along the consensus line only when that reading and a "
             "bent knee's runs fail without finding the knee bent (app.geometry.placement.leg_axis._consensus_reading).",
             "", "| axis | degrees off, median / p95 / max | ms median |", "|---|---|---|",
             f"| PCA of the surface | {stats('pca_deg')} | - |",
             f"| least squares through the compact centroids | {stats('least_squares_deg')} | "
             f"{np.median([r['least_squares_ms'] for r in rows]):.0f} |",
             f"| their consensus line | {stats('consensus_deg')} | {np.median([r['consensus_ms'] for r in rows]):.0f} |",
             "", "| case | PCA | least squares | consensus |", "|---|---|---|---|"]
    lines += [f"| {r['case']} | {r['pca_deg']:.1f} | {r['least_squares_deg']:.1f} | {r['consensus_deg']:.1f} |"
              for r in rows]
    (ROOT / "benchmarks" / "results" / "first_axis.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
