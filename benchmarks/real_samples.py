"""The real legs of tests/data read as clouds sampled from them, against their meshes.

Run:  .venv/bin/python benchmarks/real_samples.py [SEEDS]   (default 2: seeds 0 and 1; ~10 min)
      .venv/bin/python benchmarks/real_samples.py --rewrite   (the md from the json: a layout change only)
Writes benchmarks/results/real_samples.md and real_samples.json.

Each real leg (BodyParts3D's, the Visible Human female's and male's right legs) is read
as its mesh, then as clouds drawn from it, each fitted as an upload is, and every point
of the order form (benchmarks.chart_accuracy.chart_points) compared with the mesh's:

- sparse: 4,000, 5,000, 6,000 and 8,000 of its vertices (a body mesh's vertices, a
  registered template's), drawn at random without replacement;
- dense: 40,000 and 120,000 points on its skin (area-weighted, trimesh's
  ``sample_surface``) with 0.5 or 1 mm of Gaussian noise (a scanner's cloud).

Reported: which samples fit; per point the |sample - mesh| p50 / p95 / max; how many
readings the record states an uncertainty for (``uncertainty_mm``: a girth the scan
leaves uncertain, a length whose point's height is), how many of those it reaches, and
the errors past the targets (3 mm for a girth, 10 mm for a length: the reproducibility of
a hand-placed point) that nothing states - the numbers the service would stand behind
and should not.  No tape truth here: the mesh's reading is the reference.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.geometry.scan.reader import load_scan  # noqa: E402
from benchmarks.chart_accuracy import GIRTHS, LENGTHS, REAL, chart_points  # noqa: E402
from benchmarks.provenance import environment, environment_line  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results"
VERTEX_SAMPLES = (4_000, 5_000, 6_000, 8_000)
SKIN_SAMPLES = ((40_000, 0.5), (40_000, 1.0), (120_000, 1.0))
#: an error past this and unstated is a number the service should not stand behind (mm)
GIRTH_TARGET_MM = 3.0
LENGTH_TARGET_MM = 10.0


def samples(scan, seed: int) -> list[tuple[str, np.ndarray]]:
    """(name, points (n, 3) mm) of the clouds drawn from one real leg's mesh."""
    out = []
    for n in VERTEX_SAMPLES:
        picked = np.random.default_rng(seed).choice(len(scan.points_mm), n, replace=False)
        out.append((f"vertices {n} seed {seed}", scan.points_mm[picked]))
    mesh = trimesh.Trimesh(scan.points_mm, scan.faces, process=False)
    for n, noise in SKIN_SAMPLES:
        points, _ = trimesh.sample.sample_surface(mesh, n, seed=seed)
        noisy = points + np.random.default_rng(seed).normal(0.0, noise, points.shape)
        out.append((f"skin {n} noise {noise:g} seed {seed}", noisy))
    return out


def main(seeds: int = 2) -> dict:
    rows: list[dict] = []
    for name, side in REAL:
        scan = load_scan(ROOT / "tests" / "data" / "real" / name)
        reference = chart_points(scan, side)
        for seed in range(seeds):
            for sample, points in samples(scan, seed):
                cloud = load_scan(trimesh.PointCloud(points).export(file_type="ply"), file_type="ply", units="mm")
                read = chart_points(cloud, side)
                row = {"leg": name, "sample": sample, "outcome": read["outcome"], "errors": {}, "stated": {}}
                if read["outcome"] == "fit":
                    for point in GIRTHS + LENGTHS:
                        if read.get(point) is not None and reference.get(point) is not None:
                            row["errors"][point] = read[point] - reference[point]
                            row["stated"][point] = read["uncertainty"].get(point)
                rows.append(row)
                print(f"{name} {sample}: {read['outcome']}", file=sys.stderr)
    summary = {"environment": environment(), "seeds": seeds, "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "real_samples.json").write_text(json.dumps(summary, indent=1))
    (RESULTS / "real_samples.md").write_text(markdown(summary))
    return summary


def markdown(summary: dict) -> str:
    rows = summary["rows"]
    fitted = [r for r in rows if r["outcome"] == "fit"]
    lines = [
        "# The real legs read as clouds sampled from them (benchmarks/real_samples.py)",
        "",
        environment_line(summary["environment"]),
        "",
        f"{len(rows)} samples ({summary['seeds']} seeds), {len(fitted)} fitted; refused: "
        + (", ".join(f"{r['leg']} {r['sample']} ({r['outcome']})" for r in rows if r["outcome"] != "fit") or "none")
        + ".  |sample - mesh|, mm; stated: the record gives the reading's uncertainty_mm.",
        "",
        "| point | n | p50 | p95 | max | stated | stated and reaching the error | past the target, unstated |",
        "|---|---|---|---|---|---|---|---|",
    ]
    unstated: list[str] = []
    for point in GIRTHS + LENGTHS:
        pairs = [(r["errors"][point], r["stated"][point], r) for r in fitted if point in r["errors"]]
        if not pairs:
            continue
        error = np.abs([e for e, _, _ in pairs])
        stated = [(abs(e), s) for e, s, _ in pairs if s is not None]
        target = GIRTH_TARGET_MM if point in GIRTHS else LENGTH_TARGET_MM
        past = [(e, r) for e, s, r in pairs if s is None and abs(e) > target]
        unstated.extend(f"{r['leg']} {r['sample']}: {point} {e:+.1f} mm" for e, r in past)
        lines.append(f"| {point} | {len(pairs)} | {np.median(error):.2f} | {np.percentile(error, 95):.2f} | "
                     f"{error.max():.2f} | {len(stated)} | {sum(e <= s for e, s in stated)} | {len(past)} (> {target:g}) |")
    lines += ["", "Errors past the target that the record does not state:", ""]
    lines += [f"- {line}" for line in unstated] or ["- none"]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    if sys.argv[1:2] == ["--rewrite"]:
        (RESULTS / "real_samples.md").write_text(markdown(json.loads((RESULTS / "real_samples.json").read_text())))
    else:
        main(*(int(a) for a in sys.argv[1:2]))
