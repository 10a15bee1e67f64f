"""Fitting-core benchmark: accuracy on the real legs and speed on one core.

Run:  .venv/bin/python benchmarks/bench_fit.py   (or `make bench`)
Writes benchmarks/results/fit.md (and fit.json with the raw numbers).

Every time is the median of repeated runs, reported beside a reference measured in the
same run on the same data (trimesh's own load of the file, scipy's BSpline evaluation,
the paper's Algorithm 1), because the machines are noisy.  Set OMP/BLAS threads to 1
(done below) so the numbers are one-core numbers.
"""

from __future__ import annotations

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import io  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import trimesh  # noqa: E402
from scipy.interpolate import BSpline  # noqa: E402
from scipy.spatial import ConvexHull, cKDTree  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.geometry.fit.pipeline import FitOptions, fit_scan  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from app.geometry.sections.polar import ray_angles, star_hull_perimeters  # noqa: E402
from app.geometry.spline.distance import algorithm1_distances, dense_grid, newton_distances, refine_seeds  # noqa: E402
from app.geometry.spline.nurbs import evaluate_grid  # noqa: E402
from app.records.codec import record_from_fit  # noqa: E402
from benchmarks.corpus.degrade import coarsen  # noqa: E402
from benchmarks.ratios import paired_ratio  # noqa: E402

DATA = ROOT / "tests" / "data" / "real"
RESULTS = ROOT / "benchmarks" / "results"
LEGS = [
    ("bodyparts3d_right_leg.stl", None),
    ("vh_female_skin.glb", "left"),
    ("vh_female_skin.glb", "right"),
    ("vh_male_skin.glb", "left"),
    ("vh_male_skin.glb", "right"),
]


def median_time(fn, repeat: int = 9) -> float:
    fn()  # warm-up
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def accuracy_rows() -> list[dict]:
    rows = []
    for file, side in LEGS:
        scan = load_scan(DATA / file)
        for mode in ("paper", "paper_stacked"):
            for m in (8, 15):
                start = time.perf_counter()
                result = fit_scan(scan, FitOptions(side=side, points_per_layer=m, mode=mode))
                seconds = time.perf_counter() - start
                record = record_from_fit(result, scan.source_format, scan.units, seconds).to_dict()
                surface_bytes = len(json.dumps(record["surface"]).encode())
                rows.append(
                    {
                        "leg": f"{file.split('.')[0]}{'/' + side if side else ''}",
                        "mode": mode,
                        "m": m,
                        "E_alg1_radius": result.error.error_index,
                        "E_exact_radius": result.error.error_index_exact,
                        "E_alg1_diameter": result.error.error_index_diameter,
                        "E_exact_diameter": result.error.error_index_exact_diameter,
                        "max_error_mm": result.error.max_error_mm,
                        "landmarks": result.landmarks.as_dict(),
                        "record_bytes": len(json.dumps(record).encode()),
                        "surface_bytes": surface_bytes,
                        "stages": dict(result.timings),
                        "n_error_points": result.error.n_points,
                        "anterior_cue": result.frame.anterior_cue,
                    }
                )
    return rows


def leg_of_faces(leg: trimesh.Trimesh, target_faces: int) -> trimesh.Trimesh:
    """The leg retessellated to about ``target_faces`` triangles: subdivided until finer,
    then vertex-clustered (corpus.degrade.coarsen) with the cell size bisected (mm)."""
    fine = leg
    while len(fine.faces) < target_faces:
        fine = fine.subdivide()
    if len(fine.faces) < 1.1 * target_faces:
        return fine
    lo, hi = 0.01, 20.0
    for _ in range(18):
        cell = float(np.sqrt(lo * hi))
        vertices, faces = coarsen(fine.vertices, fine.faces, cell)
        lo, hi = (cell, hi) if len(faces) > target_faces else (lo, cell)
    return trimesh.Trimesh(vertices, faces, process=True)


def load_ratio_rows(leg: trimesh.Trimesh, pairs: int = 9) -> list[dict]:
    """calf-nurbs fit end to end (read + place + fit + record) against trimesh's own load
    of the same binary STL, at the face counts issue 21 names: ``pairs`` times a load then
    a fit, each pair's ratio read on one moment's machine (measured apart, the two medians'
    ratio at 200k faces ranged 3.8x-6.2x over three runs of one commit as the load's own
    time drifted 190-268 ms); the median of the pairs' ratios with its quartiles."""
    rows = []
    for target in (27_000, 200_000):
        mesh = leg if abs(len(leg.faces) - target) < 0.1 * target else leg_of_faces(leg, target)
        data = mesh.export(file_type="stl")

        def load(data=data):
            return trimesh.load(io.BytesIO(data), file_type="stl")

        def fit(data=data):
            return record_from_fit(fit_scan(load_scan(data, file_type="stl")), "stl", "mm")

        load(), fit()  # warm-up
        loads, fits = [], []
        for _ in range(pairs):
            for run, times in ((load, loads), (fit, fits)):
                start = time.perf_counter()
                run()
                times.append(time.perf_counter() - start)
        paired = paired_ratio(fits, loads)
        rows.append({"faces": int(len(mesh.faces)), "trimesh_load_s": float(np.median(loads)),
                     "fit_s": float(np.median(fits)), "ratio": paired["median"], "paired": paired,
                     "target": 1.5 if target > 100_000 else 4.0})
    return rows


def speed_rows() -> dict:
    leg = trimesh.load(DATA / "bodyparts3d_right_leg.stl")
    dense = leg.subdivide()  # 4x the faces: ~108k
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "leg_100k.stl"
        dense.export(path)
        data = path.read_bytes()
    faces = len(dense.faces)
    t_load = median_time(lambda: trimesh.load(io.BytesIO(data), file_type="stl"))
    t_fit = median_time(lambda: fit_scan(load_scan(data, file_type="stl")))
    result = fit_scan(load_scan(data, file_type="stl"))

    # a 100k-point cloud of the same leg (binary PLY, no faces, no normals): read + fit,
    # against the 100k-face mesh's read + fit in the same run
    cloud_points, _ = trimesh.sample.sample_surface(leg, 100_000, seed=3)
    cloud = trimesh.PointCloud(cloud_points).export(file_type="ply")
    t_cloud = median_time(lambda: fit_scan(load_scan(cloud, file_type="ply")))
    cloud_result = fit_scan(load_scan(cloud, file_type="ply"))

    surface = result.surface
    u = np.linspace(0, 1, 72, endpoint=False)
    v = np.linspace(0, 1, 200)
    t_eval = median_time(lambda: evaluate_grid(surface, u, v), repeat=200)
    nu, nv = surface.shape

    def scipy_grid():  # reference: scipy BSpline, u then v (weights are 1 in paper mode)
        rows = BSpline(surface.knots_u, surface.control_points.reshape(nu, -1), 3)(u).reshape(len(u), nv, 3)
        return BSpline(surface.knots_v, np.transpose(rows, (1, 0, 2)), 3)(v)

    t_scipy = median_time(scipy_grid, repeat=200)

    # tape (convex hull) perimeters of a thigh's worth of sections: ours, all at once,
    # against scipy's ConvexHull one section at a time (app.geometry.sections.polar)
    hull_angles = ray_angles(360)
    ring_rng = np.random.default_rng(5)
    hull_radii = (80.0 + 6.0 * np.sin(3 * hull_angles + ring_rng.uniform(0, 6, (300, 1)))
                  + 4.0 * np.sin(7 * hull_angles) + ring_rng.normal(0.0, 0.3, (300, 360)))
    t_hull = median_time(lambda: star_hull_perimeters(hull_radii, hull_angles))
    t_qhull = median_time(lambda: [ConvexHull(np.column_stack([r * np.cos(hull_angles), r * np.sin(hull_angles)])).area
                                   for r in hull_radii])

    # exact error over 50k points sampled on the scanned calf
    scan = load_scan(DATA / "bodyparts3d_right_leg.stl")
    fit = fit_scan(scan)
    local = fit.frame.to_calf(scan.points_mm)
    mesh = trimesh.Trimesh(local, scan.faces, process=False)
    samples, _ = trimesh.sample.sample_surface(mesh, 300_000, seed=1)
    samples = samples[(samples[:, 2] >= 0) & (samples[:, 2] <= fit.landmarks.D.height_mm)][:50_000]
    length = fit.landmarks.D.height_mm

    def seeds():
        uu, vv, grid = dense_grid(fit.surface, length)
        tree = cKDTree(grid.reshape(-1, 3), balanced_tree=False, compact_nodes=False)
        return uu, vv, grid, tree

    def algorithm1():
        uu, vv, grid, tree = seeds()
        return algorithm1_distances(samples, grid, tree)

    def exact():
        uu, vv, grid, tree = seeds()
        _, nearest = tree.query(samples)
        iu, iv = np.divmod(nearest, grid.shape[1])
        return newton_distances(fit.surface, samples, *refine_seeds(samples, uu, vv, grid, iu, iv))

    t_alg1 = median_time(algorithm1, repeat=5)
    t_exact = median_time(exact, repeat=5)
    return {
        "faces": faces,
        "trimesh_load_s": t_load,
        "fit_end_to_end_s": t_fit,
        "fit_over_load": t_fit / t_load,
        "fit_stages": dict(result.timings),
        "cloud_points": int(len(cloud_points)),
        "cloud_fit_end_to_end_s": t_cloud,
        "cloud_fit_stages": dict(cloud_result.timings),
        "grid_eval_ms": t_eval * 1e3,
        "scipy_grid_eval_ms": t_scipy * 1e3,
        "hull_300_ms": t_hull * 1e3,
        "qhull_300_ms": t_qhull * 1e3,
        "exact_50k_s": t_exact,
        "alg1_50k_s": t_alg1,
        "n_points": int(len(samples)),
        "load_ratios": load_ratio_rows(leg),
    }


def percent(x: float) -> str:
    return f"{100 * x:.2f}%"


def write_markdown(rows: list[dict], speed: dict) -> str:
    lines = [
        "# Fitting-core benchmark",
        "",
        f"Machine: {platform.processor() or platform.machine()}, Python {platform.python_version()}, "
        f"numpy {np.__version__}, one BLAS thread. Reproduce: `make bench` "
        "(or `.venv/bin/python benchmarks/bench_fit.py`).",
        "",
        "## Speed (medians; ratios against a reference timed in the same run)",
        "",
        "| what | median | reference (same run) | ratio | target |",
        "|---|---|---|---|---|",
        f"| fit a {speed['faces']:,}-face leg end to end (read + fit + record stats) | "
        f"{speed['fit_end_to_end_s'] * 1e3:.0f} ms | trimesh.load of the same STL: {speed['trimesh_load_s'] * 1e3:.0f} ms | "
        f"{speed['fit_over_load']:.2f}x | < 300 ms and < 5x |",
        f"| fit a {speed['cloud_points']:,}-point cloud of the same leg end to end (binary PLY read + fit) | "
        f"{speed['cloud_fit_end_to_end_s'] * 1e3:.0f} ms | the {speed['faces']:,}-face mesh, read + fit: "
        f"{speed['fit_end_to_end_s'] * 1e3:.0f} ms | {speed['cloud_fit_end_to_end_s'] / speed['fit_end_to_end_s']:.2f}x | "
        "< 300 ms |",
        f"| evaluate the surface on a 200 x 72 grid | {speed['grid_eval_ms']:.3f} ms | scipy BSpline, u then v: "
        f"{speed['scipy_grid_eval_ms']:.3f} ms | {speed['grid_eval_ms'] / speed['scipy_grid_eval_ms']:.2f}x | < 1 ms |",
        f"| tape (convex hull) perimeters of 300 sections x 360 rays, all at once | {speed['hull_300_ms']:.1f} ms | "
        f"scipy ConvexHull per section: {speed['qhull_300_ms']:.1f} ms | {speed['hull_300_ms'] / speed['qhull_300_ms']:.2f}x | "
        "< 1x (else ConvexHull) |",
        f"| exact (Newton) error of {speed['n_points']:,} points, incl. seeding grid + k-d tree | "
        f"{speed['exact_50k_s'] * 1e3:.0f} ms | paper's Algorithm 1 on the same points: {speed['alg1_50k_s'] * 1e3:.0f} ms | "
        f"{speed['exact_50k_s'] / speed['alg1_50k_s']:.2f}x | < 250 ms |",
        *(f"| `calf-nurbs fit` of the leg at {row['faces']:,} faces (read + place + fit + record) | "
          f"{row['fit_s'] * 1e3:.0f} ms | trimesh.load of the same STL: {row['trimesh_load_s'] * 1e3:.0f} ms | "
          f"{row['ratio']:.2f}x ({row['paired']['p25']:.2f}-{row['paired']['p75']:.2f}) | "
          f"< {row['target']:g}x{'' if row['ratio'] < row['target'] else ' (not met)'} |"
          for row in speed["load_ratios"]),
        "",
        "Stages of the 100k-face fit (one run, s): "
        + ", ".join(f"{k} {v:.3f}" for k, v in speed["fit_stages"].items()),
        "",
        "Stages of the 100k-point cloud fit (one run, s): "
        + ", ".join(f"{k} {v:.3f}" for k, v in speed["cloud_fit_stages"].items()),
        "",
        "## Accuracy on the real legs",
        "",
        "E is the paper's error index, formula 4: RMS of point-to-surface distance over the mean radius of the",
        "point's cross-section, over every scan vertex between B and D. `alg1` is the paper's Algorithm 1 on",
        "a 360 x ~1/mm triangulated resampling; `exact` is Newton point inversion. The diameter form is E / 2.",
        "",
        "| leg | mode | m | E alg1 (radius) | E exact (radius) | E alg1 (diameter) | E exact (diameter) | max error mm | B / B1 / C / D height mm | B / B1 / C / D girth mm | record bytes (surface) | fit s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lm = r["landmarks"]
        heights = " / ".join(f"{lm[k]['height_mm']:.0f}" for k in ("B", "B1", "C", "D"))
        girths = " / ".join(f"{lm[k]['circumference_mm']:.0f}" for k in ("B", "B1", "C", "D"))
        lines.append(
            f"| {r['leg']} | {r['mode']} | {r['m']} | {percent(r['E_alg1_radius'])} | {percent(r['E_exact_radius'])} | "
            f"{percent(r['E_alg1_diameter'])} | {percent(r['E_exact_diameter'])} | {r['max_error_mm']:.2f} | {heights} | "
            f"{girths} | {r['record_bytes']:,} ({r['surface_bytes']:,}) | {sum(r['stages'].values()):.3f} |"
        )
    paper15 = [r for r in rows if r["mode"] == "paper" and r["m"] == 15]
    paper8 = [r for r in rows if r["mode"] == "paper" and r["m"] == 8]
    stacked15 = [r for r in rows if r["mode"] == "paper_stacked" and r["m"] == 15]
    mean = lambda rs, k: float(np.mean([r[k] for r in rs]))  # noqa: E731
    lines += [
        "",
        "Time per stage (s), paper mode, m = 15:",
        "",
        "| leg | " + " | ".join(paper15[0]["stages"]) + " |",
        "|---|" + "---|" * len(paper15[0]["stages"]),
    ]
    for r in paper15:
        lines.append(f"| {r['leg']} | " + " | ".join(f"{v:.3f}" for v in r["stages"].values()) + " |")
    lines += [
        "",
        "## How this compares with the paper",
        "",
        f"- Paper mode, 7 x 15: mean E = {percent(mean(paper15, 'E_exact_radius'))} by radius = "
        f"{percent(mean(paper15, 'E_exact_diameter'))} by diameter over these five legs; 7 x 8: "
        f"{percent(mean(paper8, 'E_exact_radius'))} / {percent(mean(paper8, 'E_exact_diameter'))}. "
        "The paper reports 0.37% +- 0.03% (7 x 15, 260 subjects) and 0.63% (7 x 8, one subject).",
        "- The paper's figures are most likely the **diameter** form. Formula 4 divides by the mean radius r_k, "
        "but the text says the size indicator is the averaged diameter, and a plain least-squares surface with "
        "7 x 15 control points on a real standing leg gives 0.77% by radius / 0.38% by diameter (7 x 8: 1.27% / "
        "0.63%): only the diameter reading matches 0.37% and 0.63%. Our diameter-form values land in the "
        "same range; the radius form, which formula 4 literally defines, is what the record calls `error_index`.",
        f"- The literal reading of section 2.4 (`paper_stacked`: the layers' control polygons used as the "
        f"surface's control rows without interpolating along the leg) gives "
        f"{percent(mean(stacked15, 'E_exact_radius'))} by radius at 7 x 15, two to three times worse, because the "
        "surface then passes through the B and D layers only. The paper's reported accuracy is only reachable "
        "when the surface interpolates the feature points in both directions (\"averaged knot vectors in both "
        "u, v directions were utilized to fit the feature points\"), which is our default `paper` mode.",
        "- Why ours differ from 0.37%: (1) the paper's scans come from a [TC]2 NX-16 standing scanner at 5 deg x "
        "1 mm, so the 'scan dots' are already the smooth resampled grid; ours are the raw vertices of remodelled "
        "or MRI-derived skins, which carry folds and facets the 7-layer model cannot follow; (2) the VH bodies lie "
        "supine with plantar-flexed feet, so their calves are flattened against the table and the B1 region "
        "(Achilles tendon) is sharper than a standing leg's - the largest errors sit at B1 and below D, as the "
        "paper also observes; (3) 5 legs, not 260.",
        "",
        "Rows are produced by `benchmarks/bench_fit.py`; the raw numbers are in `fit.json`.",
    ]
    return "\n".join(lines) + "\n"


def main() -> None:
    RESULTS.mkdir(parents=True, exist_ok=True)
    speed = speed_rows()
    rows = accuracy_rows()
    (RESULTS / "fit.json").write_text(json.dumps({"speed": speed, "accuracy": rows}, indent=1))
    markdown = write_markdown(rows, speed)
    (RESULTS / "fit.md").write_text(markdown)
    print(markdown)


if __name__ == "__main__":
    main()
