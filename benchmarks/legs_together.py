"""Two legs scanned standing close together: what the service answers.

Run:  .venv/bin/python benchmarks/legs_together.py [LEGS] [SEED]   (default 12 41)
Writes benchmarks/results/legs_together.md and legs_together.json (legs_together-seedN.*
for another seed).

Each of LEGS pairs of generated legs (an ANSUR II subject's MakeHuman legs, feet to
hips, benchmarks/corpus, mm) is posed with its legs turned towards each other about
the hip joints (:func:`benchmarks.corpus.makehuman.adduct_legs`) by the angle at which
they first touch below the knee joint (closest vertices under 1.5 mm apart, found by
bisection), plus :data:`POSES`: 1.5 and 0.5 degrees short of it (feet together, the
closest skin 30-45 and 10-20 mm apart), just touching, and 0.4 degrees past it (the
skins pass into each other by a few mm at the knees or ankles, where a body's would
press flat).  Each pose is scanned as
a mesh (STL) and as a cloud of 60-120k points, moved rigidly, with the side given (two
legs: the service asks which).

A scan is answered right when it is fitted with cB, cB1, cC and cD within
:data:`OFF_MM` of the posed leg's own girths (measured on its whole skin, as the
robustness corpus does), or refused with a reason that names two legs or a partial view
(the service could not tell the legs apart and says so).  A fit more than OFF_MM off,
or a refusal naming an ankle, calf or knee the scan holds, is wrong, and listed.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.geometry.placement.place import TOUCHING_LEGS_WARNING  # noqa: E402
from benchmarks.corpus import degrade  # noqa: E402
from benchmarks.corpus.cases import Case, CaseSpec  # noqa: E402
from benchmarks.corpus.evaluate import run_case  # noqa: E402
from benchmarks.corpus.makehuman import GeneratedLegs, adduct_legs, ansur_subjects, leg_submesh, sized_legs  # noqa: E402
from benchmarks.corpus.truth import measure_truth  # noqa: E402
from benchmarks.provenance import environment, environment_line  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
#: degrees past (+) or short of (-) the angle at which the legs first touch
POSES = {"apart": -1.5, "close": -0.5, "touching": 0.0, "pressed": 0.4}
FORMATS = ("mesh", "cloud")
OFF_MM = 10.0
TOUCH_MM = 1.5
#: refusals that say the scan is two legs the service could not separate, or a leg not
#: seen all round: honest answers to a pair pressed together
HONEST_REFUSALS = ("several_legs", "side_not_found", "partial_view")


def closest_gap_mm(legs: GeneratedLegs) -> float:
    """The least distance (mm) between a vertex of one leg and one of the other, below
    50 mm above the knee joints (shins, knees, feet): 0 where the skins cross."""
    v = legs.vertices
    low = v[:, 1] < max(legs.joints["l-knee"][1], legs.joints["r-knee"][1]) + 50.0
    left, right = v[low & (v[:, 0] > 0)], v[low & (v[:, 0] < 0)]
    return float(cKDTree(right).query(left, k=1)[0].min())


def touching_angle(legs: GeneratedLegs) -> float:
    """The adduction (degrees) at which the legs' closest gap first falls under TOUCH_MM."""
    lo, hi = 0.0, 20.0
    for _ in range(14):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if closest_gap_mm(adduct_legs(legs, mid)) > TOUCH_MM else (lo, mid)
    return hi


def pair_cases(index: int, rng: np.random.Generator):
    """The cases of one pair of legs: every pose in every format."""
    subject_index = int(rng.integers(len(ansur_subjects())))
    legs = sized_legs(ansur_subjects()[subject_index], rng)
    touch = touching_angle(legs)
    for pose, extra in POSES.items():
        posed = adduct_legs(legs, touch + extra)
        gap = closest_gap_mm(posed)
        sign = float(rng.choice([1.0, -1.0]))  # +1 MakeHuman's left leg (x > 0)
        prefix = "l" if sign > 0 else "r"
        truth = measure_truth(leg_submesh(posed.vertices, posed.faces, sign), posed.joints[f"{prefix}-ankle"],
                              posed.joints[f"{prefix}-knee"])
        pair = trimesh.Trimesh(posed.vertices, posed.faces, process=False)
        for fmt in FORMATS:
            motion = degrade.rigid_motion(rng)
            notes = {"subject": subject_index, "pose": pose, "adduction_deg": round(touch + extra, 2),
                     "touching_deg": round(touch, 2), "closest_gap_mm": round(gap, 1)}
            if fmt == "cloud":
                cloud = degrade.sample_cloud(pair, int(rng.integers(60_000, 120_000)), rng)
                data, file_type = trimesh.PointCloud(trimesh.transform_points(cloud, motion)).export(file_type="ply"), "ply"
                notes["n_points"] = len(cloud)
            else:
                data, file_type = pair.copy().apply_transform(motion).export(file_type="stl"), "stl"
            side = "left" if sign > 0 else "right"
            spec = CaseSpec(f"pair{index:02d}-{pose}-{fmt}", f"{pose}_{fmt}", 0, subject_index)
            yield Case(spec, data, file_type, None, side, "fit", truth, motion, side, True, fmt == "cloud", notes)


def judged(result: dict) -> dict:
    """A run_case result with its errors and whether it is right (module docstring)."""
    errors = result.get("girth_error_mm") or {}
    if result["outcome"] == "fit":
        right = max(abs(e) for e in errors.values()) <= OFF_MM
    else:
        right = result["outcome"] in HONEST_REFUSALS
    return {"case": result["case"], "outcome": result["outcome"], "detail": result.get("detail"),
            "errors": {f"c{k}": round(v, 2) for k, v in errors.items()}, "warnings": result.get("warnings", []),
            "said_touching": TOUCHING_LEGS_WARNING in (result.get("warnings") or []),
            "notes": result["notes"], "seconds": round(result["seconds"], 2), "right": bool(right)}


def main(legs: int = 12, seed: int = 41) -> None:
    rng = np.random.default_rng(seed)
    rows = []
    for index in range(legs):
        for case in pair_cases(index, rng):
            row = judged(run_case(case))
            rows.append(row)
            errors = " ".join(f"{k} {v:+.1f}" for k, v in row["errors"].items())
            print(f"{row['case']:28s} gap {row['notes']['closest_gap_mm']:5.1f} {row['outcome']:14s} "
                  f"{'ok ' if row['right'] else 'BAD'} {errors}", flush=True)
    suffix = "" if seed == 41 else f"-seed{seed}"
    env = environment()
    (RESULTS / f"legs_together{suffix}.json").write_text(json.dumps({"environment": env, "legs": legs, "seed": seed,
                                                                      "cases": rows}, indent=1))
    write_markdown(rows, legs, seed, env, suffix)


def write_markdown(rows: list[dict], legs: int, seed: int, env: dict, suffix: str) -> None:
    lines = ["# Two legs standing close together", "",
             f"{environment_line(env)} Reproduce: `.venv/bin/python benchmarks/legs_together.py {legs} {seed}`; "
             "the method is in the script's docstring.", "",
             "| pose | format | cases | fitted within 10 mm | refused (two legs, partial view) | wrong | outcomes "
             "| girth error mm, abs p50 / p95 / max (fitted) | said the legs touched |",
             "|---|---|---|---|---|---|---|---|---|"]
    for pose in POSES:
        for fmt in FORMATS:
            group = [r for r in rows if r["case"].endswith(f"-{pose}-{fmt}")]
            outcomes: dict[str, int] = {}
            for r in group:
                outcomes[r["outcome"]] = outcomes.get(r["outcome"], 0) + 1
            errors = np.abs([e for r in group for e in r["errors"].values()])
            stats = (f"{np.median(errors):.2f} / {np.percentile(errors, 95):.2f} / {errors.max():.2f}"
                     if errors.size else "-")
            gaps = [r["notes"]["closest_gap_mm"] for r in group]
            fitted = sum(r["right"] and r["outcome"] == "fit" for r in group)
            refused = sum(r["right"] and r["outcome"] != "fit" for r in group)
            lines.append(f"| {pose} (gap {min(gaps):.0f}-{max(gaps):.0f} mm) | {fmt} | {len(group)} | {fitted} | "
                         f"{refused} | {len(group) - fitted - refused} | "
                         f"{', '.join(f'{k} {v}' for k, v in outcomes.items())} | {stats} | "
                         f"{sum(r.get('said_touching', False) for r in group)} |")
    wrong = [r for r in rows if not r["right"]]
    lines += ["", f"Fitted within {OFF_MM:g} mm: {sum(r['right'] and r['outcome'] == 'fit' for r in rows)} of "
              f"{len(rows)}; refused honestly: {sum(r['right'] and r['outcome'] != 'fit' for r in rows)}; "
              f"wrong: {sum(not r['right'] for r in rows)}.", ""]
    if wrong:
        lines += ["Wrong:", ""]
        for r in wrong:
            lines.append(f"- {r['case']} (adduction {r['notes']['adduction_deg']} deg, gap "
                         f"{r['notes']['closest_gap_mm']} mm): {r['outcome']} {r['errors'] or ''} {r['detail'] or ''}")
    (RESULTS / f"legs_together{suffix}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    started = time.perf_counter()
    main(*(int(a) for a in sys.argv[1:3]))
    print(f"{time.perf_counter() - started:.0f} s")
