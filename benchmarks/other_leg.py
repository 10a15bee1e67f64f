"""Two legs of which only one can be measured: the side asked, the side answered
(app.geometry.anatomy.other_leg).

Run:  .venv/bin/python benchmarks/other_leg.py [CASES] [SEED]   (default 16 3)
Writes benchmarks/results/other_leg.md and other_leg.json.

Each case is a generated adult's two legs joined at the hips (an ANSUR II subject's
MakeHuman legs, benchmarks/corpus), one of them cut 150-650 mm above its sole - no ankle,
often no calf - as a mesh or (40%) an 80k-point cloud, moved, and mirrored in 30%.  Each
scan is checked three times: asked for the cut leg, for the whole one and for no side.
A right answer: asked for the cut leg, a refusal (the service cannot measure it); asked
for the whole one or none, the whole leg labelled with its own side.  Wrong: any record
labelled with the cut leg's side (the other leg measured under its name).
"""

from __future__ import annotations

import collections
import json
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.geometry.errors import FitFailure  # noqa: E402
from app.geometry.fit.pipeline import FitOptions, check_scan  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from benchmarks.corpus import degrade  # noqa: E402
from benchmarks.corpus.makehuman import ansur_subjects, sized_legs  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"


def one_leg_cut(rng: np.random.Generator) -> tuple[bytes, str, str, dict]:
    """A scan of two legs with one cut short: its bytes, format, the cut leg's side and notes."""
    subjects = ansur_subjects()
    subject = subjects[int(rng.integers(len(subjects)))]
    legs = sized_legs(subject, np.random.default_rng(int(rng.integers(2**31))), subdivisions=2)
    vertices, faces = legs.vertices, legs.faces
    cut_sign = float(rng.choice([1.0, -1.0]))  # +1 MakeHuman's left leg (x > 0); the model stands along +y
    above_sole = float(rng.uniform(150.0, 650.0))
    gone = (vertices[:, 0] * cut_sign > 0) & (vertices[:, 1] < vertices[:, 1].min() + above_sole)
    mesh = trimesh.Trimesh(vertices, faces[~gone[faces].any(axis=1)], process=False)
    mesh.remove_unreferenced_vertices()
    as_cloud, mirror = bool(rng.random() < 0.4), bool(rng.random() < 0.3)
    motion = degrade.rigid_motion(rng)
    if mirror:
        motion = motion @ np.diag([-1.0, 1.0, 1.0, 1.0])
    data, file_type = degrade.moved_scan_file(mesh, motion, as_cloud, rng)
    cut = ("left" if cut_sign > 0 else "right") if not mirror else ("right" if cut_sign > 0 else "left")
    return data, file_type, cut, {"subject": int(subject["subjectid"]), "cut_above_sole_mm": above_sole,
                                  "cloud": as_cloud, "mirrored": mirror}


def main(cases: int = 16, seed: int = 3) -> dict:
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    rows, tally = [], collections.Counter()
    for index in range(cases):
        data, file_type, cut, notes = one_leg_cut(rng)
        whole = "right" if cut == "left" else "left"
        scan = load_scan(data, file_type=file_type)
        answers = {}
        for asked, label in ((cut, "cut"), (whole, "whole"), (None, "none")):
            try:
                placement = check_scan(scan, FitOptions(side=asked))
                answer = {"side": placement.side, "source": placement.side_source}
                verdict = "right" if placement.side == whole and label != "cut" else (
                    "WRONG" if placement.side == cut else "no side")
            except FitFailure as failure:
                answer = {"refused": failure.reason.value}
                verdict = "right" if label == "cut" else f"refused {failure.reason.value}"
            answers[label] = {**answer, "verdict": verdict}
            tally[(label, verdict)] += 1
        rows.append({"case": index, "cut_side": cut, **notes, "answers": answers})
        print(f"{index:02d} cut {cut} at {notes['cut_above_sole_mm']:.0f} mm: "
              + "; ".join(f"asked {k}: {v['verdict']}" for k, v in answers.items()), file=sys.stderr)
    result = {"cases": cases, "seed": seed, "rows": rows,
              "tally": {f"asked {label}: {verdict}": n for (label, verdict), n in sorted(tally.items())},
              "seconds": time.perf_counter() - started}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "other_leg.json").write_text(json.dumps(result, indent=1))
    lines = ["# Two legs, one cut short: the side asked and the side answered", "",
             f"`benchmarks/other_leg.py {cases} {seed}` ({result['seconds']:.0f} s). Right: asked for the cut leg, "
             "refused; asked for the whole leg or none, the whole leg with its own side.", "",
             "| asked for | answer | cases |", "|---|---|---|"]
    asked_for = {"cut": "the cut leg", "whole": "the whole leg", "none": "no side"}
    lines += [f"| {asked_for[label]} | {verdict} | {n} |" for (label, verdict), n in sorted(tally.items())]
    lines += ["", "| case | cut leg | cut above the sole (mm) | cloud | asked cut | asked whole | asked none |",
              "|---|---|---|---|---|---|---|"]
    for row in rows:
        cells = [row["answers"][k].get("refused") or f"{row['answers'][k]['side']} ({row['answers'][k]['source']})"
                 for k in ("cut", "whole", "none")]
        lines.append(f"| {row['case']} | {row['cut_side']} | {row['cut_above_sole_mm']:.0f} | {row['cloud']} | "
                     + " | ".join(cells) + " |")
    (RESULTS / "other_leg.md").write_text("\n".join(lines) + "\n")
    return result


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
