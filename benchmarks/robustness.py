"""Robustness benchmark: the fitting core on a generated corpus and on the real legs.

Run:  .venv/bin/python benchmarks/robustness.py [N_CASES] [SEED]   (default 220, 7)
      .venv/bin/python benchmarks/robustness.py --rewrite [N_CASES] [SEED]  (the md from the JSON)
Writes benchmarks/results/robustness.md and robustness.json; with another seed than the
default 7 (a hold-out corpus: scans the rules were not developed on),
robustness-seedN.md and robustness-seedN.json.

The corpus (benchmarks/corpus) is made at run time from the CC0 MakeHuman legs sized by
ANSUR II subjects; nothing generated is stored.  "Right" for a fitted case means the
expected outcome was a fit and the tape girths at B, C and D are within 10 mm of the truth
and C within 40 mm of its true height (a record of the wrong anatomy is not right; D is
on the order form too: a bent knee's D read 167 mm wide in the thigh was once counted
right);
for a refused case, the failure reason is the expected one.  A leg cropped less than a
tape's half-width (4 mm) below B (ankle_to_thigh's crops) is right refused ``no_ankle`` too:
a tape at B has no band to lie on there (see :func:`right`).  A seated leg whose thigh hides
its knee waist (expected ``no_knee``) is right too when refused as ``knee_bent`` (the
refusal names the cause), or fitted with B and C right and the record's bent-knee warning
(it stands behind B, B1 and C and says cD and lD were read on a bent knee).
"""

from __future__ import annotations

import os

for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import collections  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from app.geometry.sections import TAPE_BAND_OFFSETS_MM  # noqa: E402
from benchmarks.corpus.cases import build_case, corpus_specs  # noqa: E402
from benchmarks.corpus.evaluate import run_case  # noqa: E402
from benchmarks.provenance import environment, environment_line  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"
REAL = [("bodyparts3d_right_leg.stl", None, (215, 378, 358)), ("vh_female_skin.glb", "left", (224, 368, 369)),
        ("vh_female_skin.glb", "right", (222, 359, 354)), ("vh_male_skin.glb", "left", (223, 404, 392)),
        ("vh_male_skin.glb", "right", (223, 406, 393))]


def _suffix(seed: int) -> str:
    return "" if seed == 7 else f"-seed{seed}"


#: the start of the record's warning for a knee bent but read straight
#: (app.geometry.anatomy.thigh.bent_knee_warning)
BENT_KNEE_WARNING = "the knee is bent"
#: half the width of the band a tape is read across (mm)
TAPE_HALF_WIDTH_MM = float(TAPE_BAND_OFFSETS_MM.max())


def right(r: dict) -> bool:
    if r["expect"] != "fit":
        if r["outcome"] == r["expect"]:
            return True
        if r["kind"] == "seated" and r["expect"] == "no_knee":
            # a knee waist the bent knee's thigh hides: refused as knee_bent, the refusal
            # names the cause; fitted, the record must stand behind B and C only and say
            # that cD and lD were read on a bent knee (its warning asks for them straight)
            if r["outcome"] == "knee_bent":
                return True
            return r["outcome"] == "fit" and _calf_right(r) and any(
                w.startswith(BENT_KNEE_WARNING) for w in r["warnings"])
        return False
    if r["outcome"] != "fit":
        # a scan cropped less than a tape's half-width below B (ankle_to_thigh's crops lie
        # 0-10 mm below it) holds no band a tape at B could lie on: the service reads a
        # landmark's girth across TAPE_BAND_OFFSETS_MM and a band read on one side only is
        # no reading (app.geometry.sections.tape_band_girths); the crop's 8-degree tilt
        # cuts into B's own section by up to +-4.6 mm across a 65 mm ankle.  Above such an
        # edge an ankle rises about linearly (0.3 mm of girth per mm on robustness 220 19,
        # ankle_to_thigh-04, cropped 0.13 mm below B): nothing in the scan tells the
        # waist there from a leg still narrowing below it, so no_ankle ("re-scan from
        # below the ankle bones") is right as well as a fit
        # - measured at the section's lowest edge: the cut's tilt lifts it across the
        # ankle by cut_rise_at_ankle_mm (robustness 220 29, ankle_to_thigh_cloud-04: cut
        # 4.4 mm below B on the axis, 0.8 mm below it at the section's lowest edge)
        below_b_mm = -r["notes"].get("bottom_above_B_mm", np.nan)  # NaN: not a crop under B
        lowest_edge_below_b_mm = below_b_mm - r["notes"].get("cut_rise_at_ankle_mm", 0.0)
        if r["outcome"] == "no_ankle":
            return lowest_edge_below_b_mm < TAPE_HALF_WIDTH_MM
        # the same at the top: a knee-high crop (15-45 mm above D on the axis, its cut
        # tilted) whose section edge lies below where the leg's girth has risen above D's
        # by a tape's resolution (the truth's knee_rise_mm) shows no knee waist a tape
        # could tell from a leg still narrowing: no_knee ("re-scan over the kneecap") is
        # right as well as a fit with D at the scan's edge
        lowest_edge_above_d_mm = r["notes"].get("top_above_D_mm", np.nan) - r["notes"].get("cut_drop_at_knee_mm", 0.0)
        return r["outcome"] == "no_knee" and lowest_edge_above_d_mm < r["notes"].get("knee_rise_mm", np.nan)
    return _calf_right(r) and abs(r["girth_error_mm"]["D"]) <= 10


def _calf_right(r: dict) -> bool:
    g, h = r["girth_error_mm"], r["height_error_mm"]
    return abs(g["B"]) <= 10 and abs(g["C"]) <= 10 and abs(h["C"]) <= 40


def stats(values) -> str:
    a = np.abs(np.asarray(values, dtype=float))
    if not a.size:
        return "-"
    return f"{np.median(a):.2f} / {np.percentile(a, 95):.2f} / {a.max():.2f}"


def main(n: int = 220, seed: int = 7) -> None:
    rows = []
    for spec in corpus_specs(n, seed):
        case = build_case(spec)
        r = run_case(case)
        r["right"] = right(r)
        r["true_side"] = case.true_side
        r["foot"] = case.foot_in_scan
        r["side_given"] = case.side
        rows.append(r)
        print(f"{spec.case_id:24s} {r['outcome']:14s} {'ok ' if r['right'] else 'BAD'} {r['seconds']:.2f}s", flush=True)
    real = []
    for file, side, (b, c, d) in REAL:
        scan = load_scan(ROOT / "tests" / "data" / "real" / file)
        started = time.perf_counter()
        placement = check_scan(scan, FitOptions(side=side))
        fit = fit_scan(scan, FitOptions(side=side), placement=placement)
        seconds = time.perf_counter() - started
        tape = fit.landmarks.tape_girths_mm
        marks = fit.landmarks
        # issue 20: the surface on the skin (paper and lsq 12x24) and B1 35-85% of the way from B to C
        lsq = fit_scan(scan, FitOptions(side=side, mode="lsq", grid="12x24"), placement=placement)
        real.append({"file": file, "side": side, "seconds": seconds, "tape": tape, "reference": {"B": b, "C": c, "D": d},
                     "b1_share": (marks.B1.height_mm - marks.B.height_mm) / (marks.C.height_mm - marks.B.height_mm),
                     "skin_mm": {"paper": fit.skin.as_dict(), "lsq 12x24": lsq.skin.as_dict()},
                     "warnings": {"paper": fit.warnings, "lsq 12x24": lsq.warnings}})
    env = environment()
    (RESULTS / f"robustness{_suffix(seed)}.json").write_text(
        json.dumps({"environment": env, "cases": rows, "real": real}, indent=1, default=str))
    write_markdown(rows, real, n, seed, env)


def write_markdown(rows, real, n, seed, env: dict | None = None) -> None:
    kinds = collections.OrderedDict()
    for r in rows:
        kinds.setdefault(r["kind"], []).append(r)
    lines = [f"# Robustness: {len(rows)} generated cases (seed {seed}) and the real legs", "",
             "`.venv/bin/python benchmarks/robustness.py " + f"{n} {seed}`; one BLAS thread; times are check + fit (the upload flow).", "",
             environment_line(env), "",
             "## Outcome per degradation", "", "| degradation | cases | expected | right | outcomes |", "|---|---|---|---|---|"]
    for kind, rs in kinds.items():
        outcomes = collections.Counter(r["outcome"] for r in rs)
        expected = " / ".join(dict.fromkeys(r["expect"] for r in rs))  # a seated leg's hidden knee: no_knee
        lines.append(f"| {kind} | {len(rs)} | {expected} | {sum(r['right'] for r in rs)} | "
                     + ", ".join(f"{k} {v}" for k, v in outcomes.items()) + " |")
    inside = [r for r in rows if r["expect"] == "fit"]
    fitted = [r for r in inside if r["outcome"] == "fit"]
    lines += ["", f"- cases whose B and D lie in the scan: {len(inside)}, fitted {len(fitted)} "
              f"({100 * len(fitted) / max(len(inside), 1):.1f}%), fitted right {sum(r['right'] for r in fitted)}",
              f"- all cases right (record of the right anatomy, or the right refusal): {sum(r['right'] for r in rows)} / {len(rows)} "
              f"({100 * sum(r['right'] for r in rows) / len(rows):.1f}%)", ""]
    for label, subset in (("meshes", [r for r in fitted if not r["cloud"]]), ("point clouds", [r for r in fitted if r["cloud"]])):
        lines += [f"## Tape girth and height errors, fitted {label} ({len(subset)})", "",
                  "| landmark | girth error mm median / p95 / max | within 2 mm (B, C) or 4 mm (B1, D) | height error mm median / p95 / max |",
                  "|---|---|---|---|"]
        for name in ("B", "B1", "C", "D"):
            g = [r["girth_error_mm"][name] for r in subset]
            tol = 2.0 if name in ("B", "C") else 4.0
            share = 100 * np.mean(np.abs(g) <= tol) if g else 0
            lines.append(f"| {name} | {stats(g)} | {share:.1f}% | {stats([r['height_error_mm'][name] for r in subset])} |")
        lines.append("")
    times = [r["seconds"] for r in rows]
    lines += ["## Time per case (check + fit, s)", "",
              f"- all: median {np.median(times):.2f}, p95 {np.percentile(times, 95):.2f}, max {max(times):.2f}",
              f"- meshes: median {np.median([r['seconds'] for r in rows if not r['cloud']]):.2f}; "
              f"point clouds: median {np.median([r['seconds'] for r in rows if r['cloud']]):.2f}", ""]
    single = [r for r in rows if r["outcome"] == "fit" and r["side_given"] is None and r["foot"] and r["kind"] != "two_legs"]
    told = [r for r in single if r.get("side_found")]
    correct = sum(r["side_found"] == r["true_side"] for r in told)
    lines += ["## Side of a single leg from its foot", "",
              f"- fitted single legs with the foot and no side given: {len(single)}; side reported for {len(told)}, "
              f"right {correct}, wrong {len(told) - correct}, left null {len(single) - len(told)}", ""]
    lines += ["## Real legs (tests/data/real): tape girths against the reference table, the surface on the skin", "",
              "Surface -> scan: the record's `fit.surface_to_scan` (p99 / max mm), paper 7x15 and lsq 12x24; "
              "B1's place as a share of the way from B to C (issue 20: 0.35-0.85).", "",
              "| leg | B | C | D | B1 share | paper p99 / max | lsq 12x24 p99 / max | warnings | seconds |",
              "|---|---|---|---|---|---|---|---|---|"]
    for r in real:
        t, ref, skin = r["tape"], r["reference"], r["skin_mm"]
        paper, lsq = skin["paper"], skin["lsq 12x24"]
        warned = sum(len(w) for w in r["warnings"].values())
        lines.append(f"| {r['file']} {r['side'] or ''} | {t['B']:.1f} ({ref['B']}) | {t['C']:.1f} ({ref['C']}) | {t['D']:.1f} ({ref['D']}) | "
                     f"{r['b1_share']:.2f} | {paper['p99_mm']:.2f} / {paper['max_mm']:.2f} | {lsq['p99_mm']:.2f} / {lsq['max_mm']:.2f} | "
                     f"{warned} | {r['seconds']:.2f} |")
    bad = [r for r in rows if not r["right"]]
    lines += ["", f"## Cases not right ({len(bad)})", ""]
    for r in bad:
        lines.append(f"- {r['case']}: expected {r['expect']}, got {r['outcome']}"
                     + (f" ({r.get('detail', '')[:140]})" if r.get("detail") else
                        f" (girth errors B {r['girth_error_mm']['B']:+.1f}, C {r['girth_error_mm']['C']:+.1f}, D {r['girth_error_mm']['D']:+.1f} mm; C height {r['height_error_mm']['C']:+.0f} mm)"))
    (RESULTS / f"robustness{_suffix(seed)}.md").write_text("\n".join(lines) + "\n")


def rewrite(n: int = 220, seed: int = 7) -> None:
    """The md again from the last run's JSON, "right" judged as :func:`right` judges now."""
    data = json.loads((RESULTS / f"robustness{_suffix(seed)}.json").read_text())
    for r in data["cases"]:
        r["right"] = right(r)
    (RESULTS / f"robustness{_suffix(seed)}.json").write_text(json.dumps(data, indent=1, default=str))
    write_markdown(data["cases"], data["real"], n, seed, data.get("environment"))


if __name__ == "__main__":
    again = sys.argv[1:2] == ["--rewrite"]
    (rewrite if again else main)(*[int(a) for a in sys.argv[1 + again:]])
