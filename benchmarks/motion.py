"""One leg scanned twice, or moving while it is scanned: what the service answers.

Run:  .venv/bin/python benchmarks/motion.py [LEGS] [SEED]   (default 20 17)
Writes benchmarks/results/motion.md and motion.json.

Each of LEGS generated whole legs (an ANSUR II subject's MakeHuman leg with its foot,
benchmarks/corpus, in millimetres) is scanned clean as a mesh - the reference - and again
as each of :data:`KINDS`, every scan checked and fitted as an upload is.  A move is a
translation across the leg's axis, in a random direction, of a random size in the
kind's range:

- ``mesh_twice``: the mesh and a moved copy in one file (two passes exported unmerged);
- ``cloud_twice``: a cloud drawn from the surface and a second cloud drawn from the
  moved surface, in one file (an equal or a 70 / 30 share, 0-0.5 mm of noise);
- ``cloud_step``: one cloud, the points above a random height between the ankle and
  the thigh's middle moved (the leg swayed halfway through a scanner's sweep up it);
- ``cloud_halves``: one cloud, the points on one side of a plane along the leg moved
  (a scanner that took one side, then the other, after the leg moved).

Reported per kind: outcomes, the girths' |scan - clean| (cB, cB1, cC, cD, cE, cF, cG),
and whether a scan whose girths are more than 3 mm off says so: a warning about the
leg twice, the skin twice, the skin stepping along a seam or the surface off the skin,
or an uncertainty stated on each point that far off (its own or the clean scan's) that
covers the difference.
"""

from __future__ import annotations

import collections
import io
import json
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.geometry.errors import FitFailure  # noqa: E402
from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan  # noqa: E402
from app.geometry.garment.measuring_points import chart_of_record  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from app.records.codec import record_from_fit  # noqa: E402
from benchmarks.corpus import degrade  # noqa: E402
from benchmarks.corpus.cases import CaseSpec, build_case  # noqa: E402
from benchmarks.corpus.makehuman import ansur_subjects  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
GIRTHS = ("cB", "cB1", "cC", "cD", "cE", "cF", "cG")
#: kind -> range of the move, mm
KINDS = {"mesh_twice": (2.0, 15.0), "cloud_twice": (1.0, 6.0), "cloud_step": (2.0, 6.0), "cloud_halves": (2.0, 6.0)}
#: what a warning about a scan taken twice or moving says
SAID = ("holds this leg", "holds the skin twice", "off the scan's skin", "skin steps")
OFF_MM = 3.0


def read(data: bytes, file_type: str) -> dict:
    """The girths and warnings of a scan in mm, or its refusal."""
    scan = load_scan(data, file_type=file_type, units="mm")
    try:
        options = FitOptions()
        fit = fit_scan(scan, options, placement=check_scan(scan, options))
    except FitFailure as failure:
        return {"outcome": failure.reason.value, "detail": str(failure)[:160]}
    record = record_from_fit(fit, scan.source_format, scan.units)
    chart = chart_of_record(record.landmarks, record.scan.get("sole_mm"), "AG", record.chart)
    return {"outcome": "fit", "warnings": list(record.warnings),
            "uncertainty": {m.point.name: m.uncertainty_mm for m in chart if m.uncertainty_mm is not None},
            **{m.point.name: m.value_mm for m in chart if m.point.name in GIRTHS}}


def clean_leg(seed: int, subject: int) -> tuple[trimesh.Trimesh, np.ndarray, dict]:
    """A generated clean leg in its generating mm, its axis and its true points."""
    case = build_case(CaseSpec("motion", "mesh_clean", seed, subject))
    mesh = trimesh.load(io.BytesIO(case.data), file_type=case.file_type, process=False)
    mesh.apply_transform(np.linalg.inv(case.to_scan))
    return mesh, case.truth.axis, case.truth.points_mm


def as_cloud(points: np.ndarray) -> tuple[bytes, str]:
    return trimesh.PointCloud(points).export(file_type="ply"), "ply"


def moved_scans(mesh: trimesh.Trimesh, axis: np.ndarray, points: dict, rng: np.random.Generator) -> dict:
    """kind -> (bytes, file type, move in mm) of the leg ``mesh`` (mm) along ``axis``."""
    across = np.cross(axis, rng.normal(size=3))
    across /= np.linalg.norm(across)
    out = {}
    for kind, (low, high) in KINDS.items():
        move = float(rng.uniform(low, high))
        shift = move * across
        if kind == "mesh_twice":
            twice = trimesh.util.concatenate([mesh, mesh.copy().apply_translation(shift)])
            out[kind] = (twice.export(file_type="stl"), "stl", move)
            continue
        n = int(np.clip(mesh.area * rng.uniform(0.25, 0.5), 40_000, 120_000))
        cloud = degrade.sample_cloud(mesh, n, rng)
        if kind == "cloud_twice":
            share = float(rng.choice([0.5, 0.7]))
            second = degrade.sample_cloud(mesh, int((1 - share) * n), rng) + shift
            cloud = np.vstack([cloud[: int(share * n)], second])
            cloud = degrade.cloud_noise(cloud, float(rng.uniform(0.0, 0.5)), rng)
        elif kind == "cloud_step":
            b, thigh = points["B"] @ axis, mesh.vertices.max(axis=0) @ axis
            level = rng.uniform(b, 0.5 * (b + thigh))
            cloud[cloud @ axis > level] += shift
        else:  # cloud_halves: a plane along the leg through its middle
            side = np.cross(axis, rng.normal(size=3))
            cloud[(cloud - cloud.mean(axis=0)) @ side > 0] += shift
        out[kind] = (*as_cloud(cloud), move)
    return out


def main(legs: int = 20, seed: int = 17) -> dict:
    rng = np.random.default_rng(seed)
    started = time.perf_counter()
    rows = []
    for leg in range(legs):
        mesh, axis, points = clean_leg(int(rng.integers(2**31)), int(rng.integers(len(ansur_subjects()))))
        clean = read(mesh.export(file_type="stl"), "stl")
        for kind, (data, file_type, move) in moved_scans(mesh, axis, points, rng).items():
            got = read(data, file_type)
            errors = {g: got[g] - clean[g] for g in GIRTHS
                      if got.get(g) is not None and clean.get(g) is not None}
            said = [w for w in got.get("warnings", []) if any(s in w for s in SAID)
                    and not any(w == c for c in clean.get("warnings", []))]
            # a point more than OFF_MM off whose stated uncertainty (its own, or the clean
            # scan's: either reading may be the uncertain one) covers the difference
            stated = {g: max(got.get("uncertainty", {}).get(g, 0.0), clean.get("uncertainty", {}).get(g, 0.0))
                      for g in errors}
            unstated = [g for g, e in errors.items() if abs(e) > OFF_MM and abs(e) > stated[g]]
            rows.append({"leg": leg, "kind": kind, "move_mm": move, "outcome": got["outcome"],
                         "detail": got.get("detail"), "errors": errors, "said": said, "unstated": unstated})
            print(f"leg {leg} {kind} {move:.1f} mm: {got['outcome']} "
                  + " ".join(f"{g}{e:+.1f}" for g, e in errors.items()) + f" said {len(said)}", file=sys.stderr)
    summary = {"legs": legs, "seed": seed, "seconds": time.perf_counter() - started, "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "motion.json").write_text(json.dumps(summary, indent=1))
    write(summary)
    return summary


def kind_summary(rows: list[dict], off_mm: float) -> tuple[str, str, list[dict]]:
    """A table row's reading of ``rows`` (each {"outcome", "errors": {girth: mm}}): the
    outcomes in words ("fit 18, no_knee 2", in order of first appearance), the girth
    errors' |p50| / p95 / max in mm ("-" without any), and the rows more than ``off_mm``
    off (benchmarks/coverage.py reads its rows the same way)."""
    outcomes = collections.Counter(r["outcome"] for r in rows)
    errors = np.abs([e for r in rows for e in r["errors"].values()])
    off = [r for r in rows if r["errors"] and max(abs(e) for e in r["errors"].values()) > off_mm]
    stats = f"{np.median(errors):.2f} / {np.percentile(errors, 95):.2f} / {errors.max():.2f}" if errors.size else "-"
    return ", ".join(f"{k} {v}" for k, v in outcomes.items()), stats, off


def write(summary: dict) -> None:
    lines = [
        "# One leg scanned twice, or moving while scanned (benchmarks/motion.py)",
        "",
        f"{summary['legs']} generated whole legs (seed {summary['seed']}), each scanned clean as a mesh (the reference) "
        f"and as each kind below; {summary['seconds']:.0f} s.  Girths cB ... cG, |scan - clean| in mm; 'said' is a "
        "warning about the leg twice, the skin twice, the skin stepping along a seam or the surface off the skin that the clean scan does not carry.",
        "",
        "| kind | move mm | outcomes | girths p50 / p95 / max | scans said | scans > 3 mm off | of them said "
        "| of them with every such point's uncertainty stated |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for kind, (low, high) in KINDS.items():
        rows = [r for r in summary["rows"] if r["kind"] == kind]
        outcomes, stats, off = kind_summary(rows, OFF_MM)
        lines.append(f"| {kind} | {low:g}-{high:g} | {outcomes} | {stats} | {sum(bool(r['said']) for r in rows)} | {len(off)} | "
                     f"{sum(bool(r['said']) for r in off)} | {sum(not r['unstated'] for r in off)} |")
    lines += ["", "Per scan:", "", "| leg | kind | move mm | outcome | largest girth error mm | said |", "|---|---|---|---|---|---|"]
    for r in summary["rows"]:
        worst = max(r["errors"].items(), key=lambda item: abs(item[1]), default=None)
        lines.append(f"| {r['leg']} | {r['kind']} | {r['move_mm']:.1f} | {r['outcome']} | "
                     + (f"{worst[0]} {worst[1]:+.1f}" if worst else "-") + " | "
                     + ("; ".join(w[:70] for w in r["said"]) or "-") + " |")
    (RESULTS / "motion.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
