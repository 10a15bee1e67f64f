"""Accuracy benchmark: paper mode against lsq, an accuracy-size curve, and peer libraries.

Run:  .venv/bin/python benchmarks/accuracy.py [N_GENERATED] [SEED]   (default 36, 7)
Writes benchmarks/results/accuracy.md, accuracy.json and accuracy.png.

1. Real legs (tests/data/real): paper mode 7x8 and 7x15, lsq at the same control-point
   counts (7x8, 7x15) and larger grids: exact E (Newton distances, paper eq. 4), max
   error, record size (JSON bytes), fit time; the ratio of lsq to paper E per leg.
2. Generated legs (benchmarks/corpus, clean and degraded; the truth measured on the
   clean mesh): tape girths of the *surface* at B and C (measured on the surface at the
   truth's landmark heights along the record's own frame) against the truth.
3. Peers, the same task - a smooth surface through the 200 x 72 resampled section points
   of each real leg with ~12 x 24 control points: geomdl's ``approximate_surface``,
   splipy's ``least_square_fit`` (periodic cubic basis around, our parameters) and
   OpenCASCADE's ``GeomAPI_PointsToBSplineSurface`` (cubic, C2, its own pole count for a
   0.3 mm tolerance).  Every surface is scored the same way: the paper's Algorithm 1
   distances of the calf's scan points to a dense (0.5 degree x 0.5 mm) sampling of it.

One BLAS thread; times are medians of 3 runs on this machine (noisy: compare ratios in
one run).
"""

from __future__ import annotations

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from scipy.spatial import cKDTree  # noqa: E402

from app.geometry.fit.pipeline import MAX_ERROR_POINTS, FitOptions, fit_scan  # noqa: E402
from app.geometry.measures.surface_girths import girths  # noqa: E402
from app.geometry.measures.volume import cut_height_range  # noqa: E402
from app.geometry.placement.place import replace_leg  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from app.geometry.spline.distance import algorithm1_distances  # noqa: E402
from app.geometry.spline.lsq import LsqGrid, fit_lsq_surface, section_points  # noqa: E402
from app.geometry.spline.nurbs import NurbsSurface, evaluate_grid  # noqa: E402
from app.records.codec import record_from_fit  # noqa: E402
from benchmarks.corpus.cases import build_case, corpus_specs  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"
REAL = ROOT / "tests" / "data" / "real"
REAL_LEGS = [("bodyparts3d_right_leg.stl", None), ("vh_female_skin.glb", "left"), ("vh_female_skin.glb", "right"),
             ("vh_male_skin.glb", "left"), ("vh_male_skin.glb", "right")]
PAPER = [("paper 7x8", FitOptions(points_per_layer=8)), ("paper 7x15", FitOptions(points_per_layer=15))]
LSQ_GRIDS = ["7x8", "7x15", "10x20", "12x24", "16x32", "20x40"]
GENERATED_KINDS = ("mesh_clean", "knee_high", "holes", "noise", "cloud", "cloud_noise", "cloud_holes", "ankle_to_thigh")
PEER_ALONG, PEER_AROUND = 12, 24


def timed(fn, repeats: int = 3):
    """(last result, median seconds) of ``repeats`` calls."""
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return out, float(np.median(times))


def calf_points(scan, result) -> np.ndarray:
    """The scan points the fit scored (calf frame, B <= z <= D; a cloud thinned like the fit)."""
    leg = replace_leg(scan, result.placement)
    local = result.frame.to_calf(leg.points)
    inside = np.flatnonzero((local[:, 2] >= 0.0) & (local[:, 2] <= result.landmarks.D.height_mm))
    if leg.faces is None:
        inside = inside[:: max(len(inside) // MAX_ERROR_POINTS, 1)]
    return local[inside]


def algorithm1_score(grid: np.ndarray, points: np.ndarray, result) -> tuple[float, float]:
    """E (fraction) and max (mm) of points (n, 3) against a dense sampling grid (a, b, 3)
    of a surface (periodic in its first axis), r_k from the fit's sections."""
    tree = cKDTree(grid.reshape(-1, 3))
    distance, _, _ = algorithm1_distances(points, grid, tree)
    sections = result.sections
    valid = sections.valid
    heights, radii = sections.heights_mm[valid], sections.mean_radii()[valid]
    r_k = radii[np.clip(np.searchsorted(heights, points[:, 2]), 0, len(radii) - 1)]
    return float(np.sqrt(np.mean((distance / r_k) ** 2))), float(distance.max())


def dense_samples(result) -> tuple[int, int]:
    return 720, int(2 * result.landmarks.D.height_mm) + 1


def nurbs_from_clamped(degree_u, degree_v, knots_u, knots_v, control) -> NurbsSurface:
    control = np.asarray(control, dtype=float)
    return NurbsSurface(degree_u, degree_v, np.asarray(knots_u, float), np.asarray(knots_v, float), control,
                        np.ones(control.shape[:2]), periodic_u=False)


def peer_geomdl(data: np.ndarray):
    from geomdl import fitting

    closed = np.concatenate([data, data[:1]], axis=0)  # (73, k, 3): around closed by a repeated ray
    size_u, size_v = closed.shape[:2]
    surface = fitting.approximate_surface(closed.reshape(-1, 3).tolist(), size_u, size_v, 3, 3,
                                          ctrlpts_size_u=PEER_AROUND + 3, ctrlpts_size_v=PEER_ALONG)
    control = np.array(surface.ctrlpts).reshape(surface.ctrlpts_size_u, surface.ctrlpts_size_v, 3)
    return nurbs_from_clamped(3, 3, surface.knotvector_u, surface.knotvector_v, control)


def peer_splipy(data: np.ndarray, u: np.ndarray, v: np.ndarray, n_along: int = PEER_ALONG, n_around: int = PEER_AROUND):
    from splipy import BSplineBasis, surface_factory

    around = BSplineBasis(4, np.arange(-3, n_around + 4) / n_around, periodic=2)
    along = BSplineBasis(4, np.r_[[0.0] * 4, np.linspace(0, 1, n_along - 2)[1:-1], [1.0] * 4])
    return surface_factory.least_square_fit(data, [around, along], [u, v])


def peer_occ(data: np.ndarray, tolerance_mm: float = 0.3):
    from OCP.collections import Array2_gp_Pnt
    from OCP.GeomAbs import GeomAbs_C2
    from OCP.GeomAPI import GeomAPI_PointsToBSplineSurface
    from OCP.gp import gp_Pnt

    closed = np.concatenate([data, data[:1]], axis=0)
    a, b, _ = closed.shape
    points = Array2_gp_Pnt(1, a, 1, b)
    for i in range(a):  # the OCC array is filled point by point (part of its time)
        for j in range(b):
            points.SetValue(i + 1, j + 1, gp_Pnt(*map(float, closed[i, j])))
    surface = GeomAPI_PointsToBSplineSurface(points, 3, 3, GeomAbs_C2, tolerance_mm).Surface()
    return surface


def occ_to_nurbs(surface) -> NurbsSurface:
    nu, nv = surface.NbUPoles(), surface.NbVPoles()
    control = np.array([[[surface.Pole(i, j).X(), surface.Pole(i, j).Y(), surface.Pole(i, j).Z()]
                         for j in range(1, nv + 1)] for i in range(1, nu + 1)])

    def full(knots, mults, count):
        return np.repeat([knots(i) for i in range(1, count + 1)], [mults(i) for i in range(1, count + 1)])

    ku = full(surface.UKnot, surface.UMultiplicity, surface.NbUKnots())
    kv = full(surface.VKnot, surface.VMultiplicity, surface.NbVKnots())
    return nurbs_from_clamped(surface.UDegree(), surface.VDegree(), ku, kv, control)


def grid_of(surface: NurbsSurface, a: int, b: int) -> np.ndarray:
    u = np.linspace(*surface.domain_u, a, endpoint=False)
    v = np.linspace(*surface.domain_v, b)
    return evaluate_grid(surface, u, v)


def real_legs() -> tuple[list, list]:
    rows, peers = [], []
    for file, side in REAL_LEGS:
        scan = load_scan(REAL / file)
        name = f"{file.split('.')[0]}{' ' + side if side else ''}"
        fits = {}
        for label, options in PAPER + [(f"lsq {g}", FitOptions(mode="lsq", grid=g)) for g in LSQ_GRIDS]:
            options = FitOptions(**{**options.__dict__, "side": side})
            result, seconds = timed(lambda scan=scan, options=options: fit_scan(scan, options))
            record = record_from_fit(result, scan.source_format, scan.units).to_dict()
            nu, nv = result.surface.shape
            distinct = (nu - 3) * nv
            fits[label] = result
            rows.append({"leg": name, "method": label, "control_points": distinct,
                         "record_bytes": len(json.dumps(record["surface"])), "E": result.error.error_index_exact,
                         "max_mm": result.error.max_error_mm, "seconds": seconds})
            print(f"{name:24s} {label:12s} E {100 * result.error.error_index_exact:.3f}% max "
                  f"{result.error.max_error_mm:.2f} mm {seconds:.2f}s", flush=True)
        peers.extend(peer_rows(name, scan, fits["lsq 12x24"]))
    return rows, peers


def peer_rows(name: str, scan, result) -> list[dict]:
    points = calf_points(scan, result)
    a, b = dense_samples(result)
    sections = result.sections
    data = section_points(sections)[sections.valid].transpose(1, 0, 2)  # (72, k, 3): around, along
    u = np.linspace(0.0, 1.0, data.shape[0], endpoint=False)
    v = np.linspace(0.0, 1.0, data.shape[1])
    out = []
    e, mx = algorithm1_score(grid_of(result.surface, a, b), points, result)
    grid = LsqGrid(PEER_ALONG, PEER_AROUND)
    layers = result.landmarks.layer_heights_mm
    _, seconds = timed(lambda: fit_lsq_surface(result.sections, layers, points, grid))
    out.append({"leg": name, "method": "calf-nurbs lsq 12x24", "control_points": 12 * 24, "E": e, "max_mm": mx,
                "seconds": seconds, "note": "surface stage: the section grid, then 2 SDM rounds on the scan points"})
    gridded, seconds = timed(lambda: fit_lsq_surface(result.sections, layers, points, grid, corrections=0))
    e, mx = algorithm1_score(grid_of(gridded.surface, a, b), points, result)
    out.append({"leg": name, "method": "calf-nurbs lsq 12x24, section grid only", "control_points": 12 * 24, "E": e,
                "max_mm": mx, "seconds": seconds, "note": "no refinement on the scan points (splipy's task)"})
    uu, vv = np.linspace(0, 1, a, endpoint=False), np.linspace(0, 1, b)
    for along, around in ((PEER_ALONG, PEER_AROUND), (20, 40)):
        surface, seconds = timed(lambda along=along, around=around: peer_splipy(data, u, v, along, around))
        e, mx = algorithm1_score(np.asarray(surface(uu, vv)), points, result)
        out.append({"leg": name, "method": f"splipy least_square_fit {along}x{around}", "control_points": along * around,
                    "E": e, "max_mm": mx, "seconds": seconds, "note": "the section grid, our parameters"})
    surface, seconds = timed(lambda: peer_geomdl(data), repeats=1)
    e, mx = algorithm1_score(grid_of(surface, a, b), points, result)
    out.append({"leg": name, "method": "geomdl approximate_surface", "control_points": (PEER_AROUND + 3) * PEER_ALONG,
                "E": e, "max_mm": mx, "seconds": seconds, "note": "the section grid closed by a repeated ray"})
    surface, seconds = timed(lambda: peer_occ(data), repeats=1)
    converted = occ_to_nurbs(surface)
    e, mx = algorithm1_score(grid_of(converted, a, b), points, result)
    out.append({"leg": name, "method": "OCC PointsToBSplineSurface", "control_points": int(np.prod(converted.shape)),
                "E": e, "max_mm": mx, "seconds": seconds, "note": "tolerance 0.3 mm, its own pole count"})
    for row in out:
        print(f"  peer {row['method']:30s} E {100 * row['E']:.3f}% max {row['max_mm']:.2f} {row['seconds']:.2f}s "
              f"({row['control_points']} control points)", flush=True)
    return out


def generated(n: int, seed: int) -> list[dict]:
    specs = [s for s in corpus_specs(220, seed) if s.kind in GENERATED_KINDS]
    per_kind = max(1, n // len(GENERATED_KINDS))
    chosen = [s for kind in GENERATED_KINDS for s in [x for x in specs if x.kind == kind][:per_kind]]
    rows = []
    for spec in chosen:
        case = build_case(spec)
        scan = load_scan(case.data, file_type=case.file_type, units=case.units)
        for label, options in (("paper 7x15", FitOptions(points_per_layer=15)), ("lsq 7x15", FitOptions(mode="lsq")),
                               ("lsq 12x24", FitOptions(mode="lsq", grid="12x24"))):
            options = FitOptions(**{**options.__dict__, "side": case.side})
            try:
                result = fit_scan(scan, options)
            except Exception as exc:  # noqa: BLE001 - a refused case is reported, not fatal
                rows.append({"case": spec.case_id, "method": label, "outcome": str(getattr(exc, "reason", exc))})
                continue
            # truth heights along the truth axis, mapped to the record's frame via B
            to_gen = np.linalg.inv(case.to_scan) @ result.frame.matrix()
            origin = to_gen[:3, 3]
            b_shift = float((origin - case.truth.points_mm["B"]) @ case.truth.axis)
            heights = np.array([case.truth.heights_mm[k] - b_shift for k in ("B", "C")])
            # B lies at the surface's first ring: a truth height a fraction of a mm below
            # it is read 0.5 mm inside (the girth changes ~0.1 mm per mm at the ankle)
            low, high = cut_height_range(result.surface)
            measured = girths(result.surface, np.clip(heights, low + 0.5, high - 0.5))
            rows.append({"case": spec.case_id, "kind": spec.kind, "method": label, "outcome": "fit",
                         "E": result.error.error_index_exact, "max_mm": result.error.max_error_mm,
                         "girth_error_B_mm": measured[0].tape_mm - case.truth.girths_mm["B"],
                         "girth_error_C_mm": measured[1].tape_mm - case.truth.girths_mm["C"]})
        print(spec.case_id, [(r["method"], round(r.get("girth_error_C_mm", float("nan")), 2)) for r in rows[-3:]], flush=True)
    return rows


def chart(rows: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for family, marker in (("paper", "s"), ("lsq", "o")):
        labels = sorted({r["method"] for r in rows if r["method"].startswith(family)},
                        key=lambda m: next(r["control_points"] for r in rows if r["method"] == m))
        xs = [next(r["control_points"] for r in rows if r["method"] == m) for m in labels]
        ys = [100 * np.median([r["E"] for r in rows if r["method"] == m]) for m in labels]
        ax.plot(xs, ys, marker=marker, label=f"{family} (median of 5 real legs)")
        for x, y, m in zip(xs, ys, labels):
            ax.annotate(m.split()[1], (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("distinct control points")
    ax.set_ylabel("exact E, % of the section radius")
    ax.set_title("Accuracy against size: paper interpolation vs least squares")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / "accuracy.png", dpi=110)


def write_markdown(rows, peers, gen, n, seed) -> None:
    def med(method, key):
        values = [r[key] for r in rows if r["method"] == method]
        return float(np.median(values))

    legs = sorted({r["leg"] for r in rows}, key=[r["leg"] for r in rows].index)
    lines = [f"# Accuracy: paper mode against lsq, on the real legs and {n} generated legs (seed {seed})", "",
             f"`.venv/bin/python benchmarks/accuracy.py {n} {seed}`; one BLAS thread; times are medians of 3 runs.", "",
             "## Real legs: median over the 5 legs", "",
             "| method | control points | record surface JSON bytes | median exact E | max E | median max error mm | worst max error mm | median s |",
             "|---|---|---|---|---|---|---|---|"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    for m in methods:
        sel = [r for r in rows if r["method"] == m]
        lines.append(f"| {m} | {sel[0]['control_points']} | {int(np.median([r['record_bytes'] for r in sel]))} | "
                     f"{100 * med(m, 'E'):.3f}% | {100 * max(r['E'] for r in sel):.3f}% | {med(m, 'max_mm'):.2f} | "
                     f"{max(r['max_mm'] for r in sel):.2f} | {med(m, 'seconds'):.2f} |")
    lines += ["", "## lsq against paper at the same size, per leg (ratio of exact E; time ratio)", "",
              "| leg | lsq 7x15 / paper 7x15 | lsq 7x8 / paper 7x8 | max error lsq 7x15 mm | time lsq 7x15 / paper 7x15 |",
              "|---|---|---|---|---|"]
    ratios15, ratios8, time_ratios = [], [], []
    for leg in legs:
        get = {r["method"]: r for r in rows if r["leg"] == leg}
        r15 = get["lsq 7x15"]["E"] / get["paper 7x15"]["E"]
        r8 = get["lsq 7x8"]["E"] / get["paper 7x8"]["E"]
        t = get["lsq 7x15"]["seconds"] / get["paper 7x15"]["seconds"]
        ratios15.append(r15)
        ratios8.append(r8)
        time_ratios.append(t)
        lines.append(f"| {leg} | {r15:.2f} | {r8:.2f} | {get['lsq 7x15']['max_mm']:.2f} | {t:.2f} |")
    lines += ["", f"- median E ratio at 7x15: {np.median(ratios15):.2f} (target <= 0.75; no leg worse than paper: "
              f"{'yes' if max(ratios15) < 1 else 'no'}); at 7x8: {np.median(ratios8):.2f} (target <= 0.65)",
              f"- lsq 12x24: median E {100 * med('lsq 12x24', 'E'):.3f}% (target <= 0.40%), worst max error "
              f"{max(r['max_mm'] for r in rows if r['method'] == 'lsq 12x24'):.2f} mm (target <= 1.5)",
              f"- lsq 7x15 fit time / paper 7x15: median {np.median(time_ratios):.2f} (target <= 2)", "",
              "![accuracy against size](accuracy.png)", ""]
    lines += ["## Peers: the same surface-fitting task on the section grid (~12 x 24 control points)", "",
              "Scored alike: Algorithm 1 distances of the calf's scan points to a 0.5 degree x 0.5 mm sampling.", "",
              "| leg | method | control points | E | max error mm | seconds | note |", "|---|---|---|---|---|---|---|"]
    for r in peers:
        lines.append(f"| {r['leg']} | {r['method']} | {r['control_points']} | {100 * r['E']:.3f}% | {r['max_mm']:.2f} | "
                     f"{r['seconds']:.2f} | {r['note']} |")
    lines += ["", "## Generated legs: tape girths of the surface against the clean mesh", "",
              "| method | fitted | B girth error mm median / max | C girth error mm median / max | within 1 mm (B and C) | median exact E |",
              "|---|---|---|---|---|---|"]
    for m in ("paper 7x15", "lsq 7x15", "lsq 12x24"):
        sel = [r for r in gen if r["method"] == m and r["outcome"] == "fit"]
        total = len([r for r in gen if r["method"] == m])
        if not sel:
            continue
        b = np.abs([r["girth_error_B_mm"] for r in sel])
        c = np.abs([r["girth_error_C_mm"] for r in sel])
        within = np.mean((b <= 1.0) & (c <= 1.0))
        lines.append(f"| {m} | {len(sel)} / {total} | {np.median(b):.2f} / {b.max():.2f} | {np.median(c):.2f} / {c.max():.2f} | "
                     f"{100 * within:.0f}% | {100 * np.median([r['E'] for r in sel]):.3f}% |")
    (RESULTS / "accuracy.md").write_text("\n".join(lines) + "\n")


def main() -> None:
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 36
    seed = int(sys.argv[2]) if len(sys.argv) > 2 else 7
    rows, peers = real_legs()
    chart(rows)
    gen = generated(n, seed)
    (RESULTS / "accuracy.json").write_text(json.dumps({"real": rows, "peers": peers, "generated": gen}, indent=1, default=str))
    write_markdown(rows, peers, gen, n, seed)
    print((RESULTS / "accuracy.md").read_text())


if __name__ == "__main__":
    main()
