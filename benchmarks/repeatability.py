"""Repeatability: the same leg scanned again gives the same record.

Run:  .venv/bin/python benchmarks/repeatability.py [LEGS] [RESCANS] [SEED]   (default 16 4 7)
Writes benchmarks/results/repeatability.md and repeatability.json.

Each of LEGS generated legs (an ANSUR II subject's MakeHuman leg, benchmarks/corpus) is
scanned RESCANS times, each time with its own degradation drawn from :data:`RESCAN_KINDS`
(a clean mesh, vertex noise, holes, a cloud with or without noise, holes or uneven
density, a knee-high crop, a floor under the foot) and its own pose, units and file
format (the corpus's rigid motion, mm / cm / m, STL / PLY / OBJ / XYZ).  Every re-scan is
checked and fitted as an upload is.  Per leg and landmark the benchmark reports the range
(max - min over the re-scans) of

- the landmark's tape girth (the record's, measured on the scan),
- its height along the leg's own axis from the generating leg's ankle minimum (the
  record's frame mapped back to the generating coordinates, so B's height is
  comparable too),
- and the volume between B and D of the record's surface (% of the mean),
- and what a clinic's comparison of two of these records reports as the volume change
  (``GET /records/{a}/compare/{b}?align=B``: b aligned on a at B, over a's B to D;
  :func:`app.geometry.measures.compare.compare_surfaces`) - every re-scan against the
  leg's first, the largest |change| per leg.  An unchanged leg re-scanned should show
  no change; this is the number a lymphoedema clinic watches over time.

Targets (issue 20): every re-scan fits; girth range p95 <= 1.0 mm at B, C, D; height
range p95 <= 8 mm at B1 and D; volume range p95 <= 0.5%.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.geometry.errors import FitFailure  # noqa: E402
from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan  # noqa: E402
from app.geometry.measures.compare import compare_surfaces  # noqa: E402
from app.geometry.measures.volume import volume_between  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from app.records.codec import record_from_fit  # noqa: E402
from benchmarks.corpus.cases import CaseSpec, build_case  # noqa: E402
from benchmarks.corpus.makehuman import ansur_subjects  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
RESCAN_KINDS = ("mesh_clean", "noise", "holes", "cloud", "cloud_noise", "cloud_holes", "cloud_uneven", "knee_high",
                "knee_high_cloud", "floor")
LANDMARKS = ("B", "B1", "C", "D")


def rescan(spec: CaseSpec, surfaces: list | None = None) -> dict:
    """One re-scan checked and fitted; its record's numbers (and, into ``surfaces``, its
    surface and landmarks, for the comparisons)."""
    case = build_case(spec)
    out = {"case": spec.case_id, "kind": spec.kind, "cloud": case.is_cloud}
    try:
        scan = load_scan(case.data, file_type=case.file_type, units=case.units)
        options = FitOptions(side=case.side)
        fit = fit_scan(scan, options, placement=check_scan(scan, options))
    except FitFailure as failure:
        out.update(outcome=failure.reason.value, detail=failure.detail)
        return out
    record = record_from_fit(fit, scan.source_format, scan.units).to_dict()
    to_gen = np.linalg.inv(case.to_scan) @ np.asarray(record["frame"])
    b_shift = float((to_gen[:3, 3] - case.truth.points_mm["B"]) @ case.truth.axis)
    marks = record["landmarks"]
    if surfaces is not None:
        surfaces.append((fit.surface, marks))
    out.update(outcome="fit",
               girth_mm={n: marks[n].get("tape_girth_mm", marks[n]["circumference_mm"]) for n in LANDMARKS},
               height_mm={n: b_shift + marks[n]["height_mm"] for n in LANDMARKS},
               volume_ml=volume_between(fit.surface, marks["B"]["height_mm"] + 1e-2, marks["D"]["height_mm"] - 1e-2) / 1000,
               b1_share=(marks["B1"]["height_mm"] - marks["B"]["height_mm"]) / (marks["C"]["height_mm"] - marks["B"]["height_mm"]),
               warnings=record["warnings"])
    return out


def main(legs: int = 16, rescans: int = 4, seed: int = 7) -> dict:
    rng = np.random.default_rng(seed)
    n_subjects = len(ansur_subjects())
    per_leg = []
    started = time.perf_counter()
    for leg in range(legs):
        subject, leg_seed = int(rng.integers(n_subjects)), int(rng.integers(2**31))
        kinds = rng.choice(RESCAN_KINDS, size=rescans, replace=False)
        surfaces: list = []
        scans = [rescan(CaseSpec(f"leg{leg:02d}-{k}-{r}", str(k), int(rng.integers(2**31)), subject, leg_seed), surfaces)
                 for r, k in enumerate(kinds)]
        fitted = [s for s in scans if s["outcome"] == "fit"]
        row = {"leg": leg, "subject_index": subject, "scans": scans, "fitted": len(fitted)}
        if len(fitted) >= 2:
            row["girth_range_mm"] = {n: float(np.ptp([s["girth_mm"][n] for s in fitted])) for n in LANDMARKS}
            row["height_range_mm"] = {n: float(np.ptp([s["height_mm"][n] for s in fitted])) for n in LANDMARKS}
            volumes = np.array([s["volume_ml"] for s in fitted])
            row["volume_range_percent"] = float(100 * np.ptp(volumes) / volumes.mean())
            (first, first_marks), others = surfaces[0], surfaces[1:]
            row["compared_volume_change_percent"] = float(max(
                abs(compare_surfaces(first, first_marks, other, marks, align="B").volume_change_percent) for other, marks in others))
        per_leg.append(row)
        print(f"leg {leg}: {len(fitted)}/{rescans} fitted", {k: round(v, 1) for k, v in row.get("height_range_mm", {}).items()},
              flush=True)
    result = {"legs": legs, "rescans": rescans, "seed": seed, "seconds": time.perf_counter() - started,
              "per_leg": per_leg, "summary": summarize(per_leg, rescans)}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "repeatability.json").write_text(json.dumps(result, indent=1))
    (RESULTS / "repeatability.md").write_text(report(result))
    return result


def _stats(values: list[float]) -> dict:
    a = np.asarray(values, dtype=float)
    return {"p50": float(np.percentile(a, 50)), "p95": float(np.percentile(a, 95)), "max": float(a.max())} if len(a) else {}


def summarize(per_leg: list[dict], rescans: int) -> dict:
    ranged = [row for row in per_leg if "girth_range_mm" in row]
    failures = [(s["case"], s["outcome"], s.get("detail", "")) for row in per_leg for s in row["scans"] if s["outcome"] != "fit"]
    shares = [s["b1_share"] for row in per_leg for s in row["scans"] if s["outcome"] == "fit"]
    return {
        "fitted": sum(row["fitted"] for row in per_leg), "scans": rescans * len(per_leg), "failures": failures,
        "girth_range_mm": {n: _stats([r["girth_range_mm"][n] for r in ranged]) for n in LANDMARKS},
        "height_range_mm": {n: _stats([r["height_range_mm"][n] for r in ranged]) for n in LANDMARKS},
        "volume_range_percent": _stats([r["volume_range_percent"] for r in ranged]),
        "compared_volume_change_percent": _stats([r["compared_volume_change_percent"] for r in ranged]),
        "b1_share_of_b_to_c": _stats(shares) | {"min": float(min(shares)) if shares else None},
    }


def report(result: dict) -> str:
    s = result["summary"]
    lines = ["# Repeatability: one leg scanned again", "",
             f"`.venv/bin/python benchmarks/repeatability.py {result['legs']} {result['rescans']} {result['seed']}`: "
             f"{result['legs']} generated legs, each scanned {result['rescans']} times with its own degradation "
             f"({', '.join(RESCAN_KINDS)}), pose, units and format; {result['seconds']:.0f} s.", "",
             f"Fitted: {s['fitted']} / {s['scans']} re-scans.", "",
             "Range over the re-scans of one leg (max - min), over the legs:", "",
             "| landmark | girth p50 mm | girth p95 mm | girth max mm | height p50 mm | height p95 mm | height max mm |",
             "|---|---|---|---|---|---|---|"]
    for n in LANDMARKS:
        g, h = s["girth_range_mm"][n], s["height_range_mm"][n]
        lines.append(f"| {n} | {g['p50']:.2f} | {g['p95']:.2f} | {g['max']:.2f} | {h['p50']:.1f} | {h['p95']:.1f} | {h['max']:.1f} |")
    v = s["volume_range_percent"]
    b1 = s["b1_share_of_b_to_c"]
    c = s["compared_volume_change_percent"]
    lines += ["", f"Volume B-D range: p50 {v['p50']:.2f}%, p95 {v['p95']:.2f}%, max {v['max']:.2f}%.", "",
              "Volume change a comparison of two re-scans reports (aligned at B, over the first scan's B to D; the "
              f"largest |change| per leg): p50 {c['p50']:.2f}%, p95 {c['p95']:.2f}%, max {c['max']:.2f}%.", "",
              f"B1's place between B and C (share of the way): p50 {b1['p50']:.2f}, min {b1['min']:.2f}, max {b1['max']:.2f}.", "",
              "Targets: every re-scan fits; girth p95 <= 1.0 mm at B, C, D; height p95 <= 8 mm at B1 and D; "
              "volume p95 <= 0.5%."]
    if s["failures"]:
        lines += ["", "Re-scans that did not fit:", ""] + [f"- {c}: `{o}` - {d}" for c, o, d in s["failures"]]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:]]
    print(report(main(*args)))
