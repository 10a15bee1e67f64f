"""A scan as mesh tools export it: is it measured as the skin, or said?

Run:  .venv/bin/python benchmarks/exported_meshes.py [LEGS] [SEED]   (default 4 61)
Writes benchmarks/results/exported_meshes.md and .json (exported_meshes-seedN.* for
another seed).

For LEGS generated legs (an ANSUR II subject's MakeHuman leg, benchmarks/corpus), each
scanned as each of :data:`KINDS` (whole, knee-high, from the ankle to the thigh, midfoot
to mid-thigh, with noisy vertices), the mesh is exported again as the tools of
benchmarks/corpus/exports.py leave it (in millimetres, then back to the case's file
units and format):

- ``rounded_Xmm``: every vertex on an X mm grid (a fixed precision);
- ``hollowed_Xmm`` / ``hollowed_rims_Xmm``: a wall X mm inside the skin, a piece of its
  own or joined to the skin at its open ends (a mesh prepared for 3D printing);
- ``capped_flat`` / ``capped_low_dome`` / ``capped_dome``: every open end closed (a
  "watertight" export), flat or domed 0.25 or 0.6 of its radius high;
- ``double_sided``, ``windings_mixed``.

Each is checked and fitted as an upload is (benchmarks/corpus/evaluate.run_case) and
compared with the same case exported plain: the outcome, the girths of B, B1, C, D
against the clean mesh's truth, how far the export moved them and their heights, and
the warnings it added.  A scan read more than :data:`OFF_MM` off the plain export's
girths, or whose landmark moved more than :data:`MOVED_MM` and past the height
uncertainty either record states on it, without a new warning is counted as silent.
"""

from __future__ import annotations

import collections
import dataclasses
import io
import json
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.corpus import exports  # noqa: E402
from benchmarks.corpus.cases import CaseSpec, build_case  # noqa: E402
from benchmarks.corpus.evaluate import LANDMARKS, run_case  # noqa: E402
from benchmarks.corpus.makehuman import ansur_subjects  # noqa: E402
from benchmarks.provenance import environment, environment_line  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"
KINDS = ("mesh_clean", "knee_high", "ankle_to_thigh", "midfoot_midthigh", "noise")
#: girths further than this from the plain export's, mm, must be said
OFF_MM = 2.0
#: a landmark moved along the leg further than this from the plain export's, mm, must be said
MOVED_MM = 5.0


def variants(mesh: trimesh.Trimesh, rng: np.random.Generator) -> dict[str, trimesh.Trimesh]:
    """The exports of ``mesh`` (mm, vertices merged) by name (module docstring)."""
    out = {f"rounded_{cell:g}mm": exports.rounded_to_grid(mesh, cell) for cell in (0.5, 1.0, 2.0)}
    for wall in (1.5, 3.0):
        out[f"hollowed_{wall:g}mm"] = exports.hollowed(mesh, wall, rims=False)
        out[f"hollowed_rims_{wall:g}mm"] = exports.hollowed(mesh, wall, rims=True)
    for style in exports.CAP_HEIGHTS:
        out[f"capped_{style}"] = exports.capped(mesh, style)
    out["double_sided"] = exports.double_sided(mesh)
    out["windings_mixed"] = exports.windings_mixed(mesh, rng)
    return out


def as_file(mesh: trimesh.Trimesh, to_scan: np.ndarray, file_type: str) -> bytes:
    """``mesh`` (generating mm) in the case's file units and frame (``to_scan`` (4, 4)), as
    bytes of ``file_type``."""
    moved = mesh.copy()
    moved.apply_transform(to_scan)
    data = moved.export(file_type=file_type)
    return data.encode() if isinstance(data, str) else data


def main(legs: int = 4, seed: int = 61) -> dict:
    rng = np.random.default_rng(seed)
    started = time.perf_counter()
    subjects = ansur_subjects()
    rows = []
    for leg in range(legs):
        subject = int(rng.integers(len(subjects)))
        for kind in KINDS:
            case = build_case(CaseSpec(f"export-{leg}-{kind}", kind, int(rng.integers(2**31)), subject))
            plain = run_case(case)
            rows.append({"leg": leg, "kind": kind, "export": "plain", **_summary(plain, plain)})
            mesh = trimesh.load(io.BytesIO(case.data), file_type=case.file_type, process=True)
            mesh.apply_transform(np.linalg.inv(case.to_scan))
            for name, exported in variants(mesh, rng).items():
                got = run_case(dataclasses.replace(case, data=as_file(exported, case.to_scan, case.file_type)))
                rows.append({"leg": leg, "kind": kind, "export": name, **_summary(got, plain)})
                print(leg, kind, name, rows[-1]["outcome"], rows[-1].get("girth_moved_mm"), rows[-1]["new_warnings"][:1],
                      file=sys.stderr)
    summary = {"legs": legs, "seed": seed, "seconds": time.perf_counter() - started, "environment": environment(),
               "rows": rows}
    stem = "exported_meshes" if seed == 61 else f"exported_meshes-seed{seed}"
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{stem}.json").write_text(json.dumps(summary, indent=1))
    (RESULTS / f"{stem}.md").write_text(markdown(summary))
    return summary


def _summary(got: dict, plain: dict) -> dict:
    """One export's outcome against its plain export's: girth errors against the truth,
    how far it moved the girths and heights from the plain export's, and its new warnings."""
    row = {"outcome": got["outcome"], "plain_outcome": plain["outcome"], "detail": got.get("detail", "")[:200],
           "new_warnings": [w for w in got.get("warnings", []) if w not in plain.get("warnings", [])]}
    if got["outcome"] == "fit":
        row["girth_error_mm"] = got["girth_error_mm"]
        row["height_error_mm"] = got["height_error_mm"]
        if plain["outcome"] == "fit":
            row["girth_moved_mm"] = max(abs(got["girth_error_mm"][n] - plain["girth_error_mm"][n]) for n in LANDMARKS)
            moved = {n: abs(got["height_error_mm"][n] - plain["height_error_mm"][n]) for n in LANDMARKS}
            row["height_moved_mm"] = max(moved.values())
            row["height_moved_landmark"] = max(moved, key=moved.get)
            # a landmark's move past the height uncertainty either record states on it
            stated = {n: max(got["height_tolerance_mm"][n] or 0.0, plain["height_tolerance_mm"][n] or 0.0)
                      for n in LANDMARKS}
            row["height_moved_past_stated_mm"] = max(max(moved[n] - stated[n], 0.0) for n in LANDMARKS)
    return row


def markdown(summary: dict) -> str:
    rows = summary["rows"]
    lines = [
        "# A scan as mesh tools export it (benchmarks/exported_meshes.py)", "",
        f"`benchmarks/exported_meshes.py {summary['legs']} {summary['seed']}` ({summary['seconds']:.0f} s). "
        + environment_line(summary["environment"]), "",
        f"Each of {summary['legs']} legs scanned as {', '.join(KINDS)}, exported again as the tools of "
        "benchmarks/corpus/exports.py leave it. Outcome as the plain export's: the same outcome (a fit, or the same "
        "refusal). Girth error: |girth - the clean mesh's truth| over B, B1, C, D, mm; moved: the largest change of a "
        "girth (of a landmark's height) from the plain export's; silent: moved more than "
        f"{OFF_MM:g} mm in girth, or a landmark more than {MOVED_MM:g} mm in height and past the height uncertainty "
        "either record states on it, with no warning the plain export did not have.", "",
        "| export | scans | outcome as plain | outcomes | girth error p50 / p95 / max | girth moved max | height moved max "
        "| with new warnings | silent |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    by_export = collections.defaultdict(list)
    for row in rows:
        by_export[row["export"]].append(row)
    for name, group in by_export.items():
        outcomes = collections.Counter(r["outcome"] for r in group)
        errors = [abs(e) for r in group for e in r.get("girth_error_mm", {}).values()]
        moved = [r["girth_moved_mm"] for r in group if "girth_moved_mm" in r]
        heights = [r["height_moved_mm"] for r in group if "height_moved_mm" in r]
        silent = [r for r in group if not r["new_warnings"] and (r.get("girth_moved_mm", 0.0) > OFF_MM
                                                                 or (r.get("height_moved_mm", 0.0) > MOVED_MM
                                                                     and r.get("height_moved_past_stated_mm", 0.0) > 0))]
        lines.append(
            f"| {name} | {len(group)} | {sum(r['outcome'] == r['plain_outcome'] for r in group)} | "
            + ", ".join(f"{k} {v}" for k, v in outcomes.items()) + " | "
            + (f"{np.median(errors):.2f} / {np.percentile(errors, 95):.2f} / {max(errors):.2f}" if errors else "-")
            + " | " + (f"{max(moved):.2f}" if moved else "-") + " | " + (f"{max(heights):.1f}" if heights else "-")
            + f" | {sum(bool(r['new_warnings']) for r in group)} | {len(silent)} |")
    lines += ["", "Exports whose outcome differs from the plain export's, or that moved a reading with or without a "
              "word (girth > 1 mm, height > 3 mm):", "",
              "| leg | kind | export | outcome (plain) | girth moved | height moved (landmark; past its stated uncertainty) "
              "| new warnings or refusal |",
              "|---|---|---|---|---|---|---|"]
    for r in rows:
        changed = (r["outcome"] != r["plain_outcome"] or r.get("girth_moved_mm", 0.0) > 1.0
                   or r.get("height_moved_mm", 0.0) > 3.0)
        if r["export"] == "plain" or not changed:
            continue
        said = r["detail"] if r["outcome"] != "fit" else "; ".join(w[:90] for w in r["new_warnings"])
        lines.append(f"| {r['leg']} | {r['kind']} | {r['export']} | {r['outcome']} ({r['plain_outcome']}) | "
                     + (f"{r['girth_moved_mm']:.1f}" if "girth_moved_mm" in r else "-") + " | "
                     + (f"{r['height_moved_mm']:.1f} ({r['height_moved_landmark']}; {r['height_moved_past_stated_mm']:.1f})"
                        if "height_moved_mm" in r else "-") + f" | {said[:160] or '-'} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
