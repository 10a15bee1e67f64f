"""The speed targets of issue 21 in one table, from the fit and service benchmarks of the
same `make bench` run (benchmarks/results/fit.json and service.json).

Run:  make bench   (bench_fit.py, bench_service.py, then this)
Writes benchmarks/results/ratios.md.  Every number is a ratio measured in the
same run against a reference on the same data, in pairs taken one right after the other
(the machine's speed drifts between minutes apart): trimesh's own load of the STL, then
the fit; the core's own load + fit of a scan, then its upload.  Given: the median of the
pairs' ratios, with their quartiles.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
#: upload -> record within this multiple of the core fit (issue 21, item 5)
SERVICE_TARGET = 1.3


def paired_ratio(measured_s: list[float], reference_s: list[float]) -> dict[str, float]:
    """The ratios of pairs timed one right after the other (``measured_s[i]`` against
    ``reference_s[i]``, s): their median and quartiles {"p25", "median", "p75"}."""
    return dict(zip(("p25", "median", "p75"), np.percentile(np.divide(measured_s, reference_s), [25, 50, 75]).tolist()))


def main() -> None:
    fit = json.loads((RESULTS / "fit.json").read_text())["speed"]
    service = json.loads((RESULTS / "service.json").read_text())
    lines = [
        "# Speed ratios (one `make bench` run)",
        "",
        "| what | median | reference (same run) | ratio | target | met |",
        "|---|---|---|---|---|---|",
    ]
    for row in fit["load_ratios"]:
        lines.append(f"| `calf-nurbs fit`, {row['faces']:,}-face leg | {row['fit_s'] * 1e3:.0f} ms | trimesh.load "
                     f"{row['trimesh_load_s'] * 1e3:.0f} ms | {row['ratio']:.2f}x ({row['paired']['p25']:.2f}-"
                     f"{row['paired']['p75']:.2f}) | < {row['target']:g}x | "
                     f"{'yes' if row['ratio'] < row['target'] else 'no'} |")
    for scan, seconds in service["upload_to_record_s"].items():
        core = service["core_fit_s"][scan]
        # each upload against the core's fit just before it (bench_service.py), quartiles in brackets
        paired = service["upload_over_core"][scan]
        ratio = paired["median"]
        lines.append(f"| upload -> record, {scan} | {seconds * 1e3:.0f} ms | core load + fit {core * 1e3:.0f} ms | "
                     f"{ratio:.2f}x ({paired['p25']:.2f}-{paired['p75']:.2f}) | < {SERVICE_TARGET:g}x | "
                     f"{'yes' if ratio < SERVICE_TARGET else 'no'} |")
    (RESULTS / "ratios.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
