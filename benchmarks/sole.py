"""The floor the order form's lengths are measured from (app.geometry.anatomy.sole), on
generated whole legs scanned every way the corpus knows.

Run:  .venv/bin/python benchmarks/sole.py [LEGS] [SEED]   (default 6 21)
Writes benchmarks/results/sole.md and sole.json.

Each of LEGS generated legs (an ANSUR II subject's MakeHuman leg, benchmarks/corpus) is
scanned clean (a mesh: the reference) and again as each kind of :data:`STANDING` (the
foot stands flat and is whole: the sole must be found, lB within a few mm of the clean
scan's) and of :data:`NO_FLOOR` (cut through the foot 30-50 mm above the sole, or the foot
pointed 20-45 degrees: there is no floor, and the record must say so, not measure from
the cut or the lifted heel).  Every scan is checked and fitted as an upload is; lB is B's
height above the sole.  The table gives, per kind, how often the sole was found, |lB -
clean lB| (p50 / p95 / max) under the rule and under the one before it (the heel's plain
lowest point), and the reasons given where there is none.
"""

from __future__ import annotations

import collections
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.geometry.errors import FitFailure  # noqa: E402
from app.geometry.fit.pipeline import FitOptions, check_scan, fit_placed_leg  # noqa: E402
from app.geometry.placement import replace_leg  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from benchmarks.corpus.cases import build_case, leg_rescans  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"
STANDING = ("cloud", "cloud_noise", "cloud_outliers", "cloud_uneven", "cloud_holes", "vertex_cloud", "floor",
            "floor_cloud", "noise", "holes", "two_legs", "body_vertices", "coarse_mesh", "seated", "knee_high_cloud")
NO_FLOOR = ("midfoot_midthigh", "plantar")
#: the order form's lengths are held to 5 mm (issue 22)
LENGTH_TARGET_MM = 5.0


def sole_row(name: str, kind: str, scan, side: str | None) -> dict:
    """lB under the rule and under the heel's plain lowest point, or the fit's outcome."""
    options = FitOptions(side=side)
    try:
        placement = check_scan(scan, options)
        leg = replace_leg(scan, placement)
        result = fit_placed_leg(leg, len(scan.points_mm), options)
    except FitFailure as failure:
        return {"scan": name, "kind": kind, "outcome": failure.reason.value}
    out = {"scan": name, "kind": kind, "outcome": "fit", "foot": placement.anterior_cue == "foot",
           "lB": None if result.sole_mm is None else -result.sole_mm, "reason": result.sole_reason}
    if out["foot"]:
        local = placement.frame.to_calf(leg.points)
        out["lB_lowest_point"] = -float(local[(local[:, 1] <= 0.0) & (local[:, 2] < 0.0), 2].min())
    return out


def main(legs: int = 6, seed: int = 21) -> dict:
    started = time.perf_counter()
    rows = []
    for leg, spec in leg_rescans(legs, seed, ("mesh_clean",) + STANDING + NO_FLOOR):
        case = build_case(spec)
        scan = load_scan(case.data, file_type=case.file_type, units=case.units)
        rows.append(sole_row(spec.case_id, spec.kind, scan, case.side) | {"leg": leg})
    result = {"legs": legs, "seed": seed, "seconds": time.perf_counter() - started, "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "sole.json").write_text(json.dumps(result, indent=1))
    (RESULTS / "sole.md").write_text(report(result))
    return result


def _stats(values: list[float]) -> str:
    a = np.abs(np.asarray(values, dtype=float))
    if not len(a):
        return "-"
    return f"{np.percentile(a, 50):.1f} / {np.percentile(a, 95):.1f} / {a.max():.1f}"


def report(result: dict) -> str:
    rows = result["rows"]
    clean = {r["leg"]: r["lB"] for r in rows if r["kind"] == "mesh_clean" and r["outcome"] == "fit"}
    lines = ["# The floor the lengths are measured from (benchmarks/sole.py)", "",
             f"`.venv/bin/python benchmarks/sole.py {result['legs']} {result['seed']}`: {result['legs']} generated legs, "
             f"each scanned clean (the reference) and as every kind below; {result['seconds']:.0f} s. lB is B's height "
             "above the sole; |lB - clean lB| in mm (p50 / p95 / max) includes B's own move between scans. 'before': "
             "the heel's plain lowest point, the rule until 2026-12-04.", "",
             "| kind | fitted with the foot | sole found | \\|lB - clean\\| | before | over 5 mm (before) | no sole: reasons |",
             "|---|---|---|---|---|---|---|"]
    wrong = []
    for kind in STANDING + NO_FLOOR:
        mine = [r for r in rows if r["kind"] == kind and r["outcome"] == "fit" and r["foot"] and r["leg"] in clean]
        found = [r for r in mine if r["lB"] is not None]
        now = [r["lB"] - clean[r["leg"]] for r in found]
        before = [r["lB_lowest_point"] - clean[r["leg"]] for r in mine]
        reasons = collections.Counter(r["reason"].split(":")[0] for r in mine if r["lB"] is None)
        over = sum(abs(v) > LENGTH_TARGET_MM for v in now)
        over_before = sum(abs(v) > LENGTH_TARGET_MM for v in before)
        lines.append(f"| {kind} | {len(mine)} | {len(found)} | {_stats(now)} | {_stats(before)} | {over} ({over_before}) | "
                     + ("; ".join(f"{n} x {why}" for why, n in reasons.items()) or "-") + " |")
        expect_sole = kind in STANDING
        wrong += [r["scan"] for r in mine if (r["lB"] is not None) != expect_sole]
    lines += ["", f"- kinds whose foot stands flat and whole ({', '.join(STANDING)}): the sole must be found; kinds "
              f"without a floor ({', '.join(NO_FLOOR)}): it must not be, and the reason given instead",
              f"- scans with the wrong answer (a floor missed, or one read off a cut or a lifted heel): {len(wrong)}"
              + (f" ({', '.join(wrong)})" if wrong else ""),
              "- not fitted (the record has no lengths at all): "
              + (", ".join(f"{r['scan']} {r['outcome']}" for r in rows if r["outcome"] != "fit") or "none")]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
