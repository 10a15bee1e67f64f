"""A cloud captured in parts while the leg moved: is the seam found, and is a single
cloud left alone (app.geometry.scan.skin_seam)?

Run:  .venv/bin/python benchmarks/skin_seam.py [LEGS] [SEED]   (default 8 43)
Writes benchmarks/results/skin_seam.md and skin_seam.json (skin_seam-seedN.* for a seed
other than 43).

Each of LEGS generated whole legs (an ANSUR II subject's MakeHuman leg with its foot,
benchmarks/corpus) is read as:

- every cloud kind of the robustness corpus (benchmarks/corpus/cases.py: clean, noisy,
  stray points, one side sparser, holes, a floor, a tessellation's vertices, a body's,
  cropped), and clouds of 100k points drawn on the facets of its coarse meshes and of its
  meshes with noisy vertices (``*_facets``: a scanner that exports points resampled from
  its own mesh; their noise is not independent from point to point): one skin, no seam -
  a seam said is a false alarm;
- ``halves``: a cloud (40-120k points by area, as benchmarks/motion.py draws) whose
  points on one side of a plane along the leg, through its middle, moved 2-6 mm across
  the leg in a random direction, with 0, 0.5 or 1 mm of noise per coordinate.  Its
  girths cB ... cD are compared with the clean mesh's: a scan more than
  :data:`OFF_MM` off must say so (the seam's warning, or another about the skin: the
  surface off it, the skin twice).

And BodyParts3D's real leg (tests/data/real) as clouds drawn by area, clean and noisy:
its tibial crest is the strongest ridge a leg has.  Reported per kind: the seam's share
(app.geometry.scan.skin_seam.SkinSeam.share) p50 / max, the scans said, and for the
halves their girth errors and whether the ones off were said.
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
from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from app.geometry.scan.skin_seam import SEAM_SHARE  # noqa: E402
from app.records.codec import record_from_fit  # noqa: E402
from benchmarks.corpus import degrade  # noqa: E402
from benchmarks.corpus.cases import CaseSpec, build_case  # noqa: E402
from benchmarks.corpus.makehuman import ansur_subjects  # noqa: E402
from benchmarks.motion import as_cloud, clean_leg  # noqa: E402
from benchmarks.provenance import environment, environment_line  # noqa: E402

RESULTS = ROOT / "benchmarks" / "results"
CLOUD_KINDS = ("cloud", "cloud_noise", "cloud_outliers", "cloud_uneven", "cloud_holes", "floor_cloud", "vertex_cloud",
               "knee_high_cloud", "ankle_to_thigh_cloud", "body_vertices", "sparse_leg_vertices")
#: meshes whose facets a cloud is drawn on: coarse ones, and ones with noisy vertices
FACET_KINDS = ("coarse_mesh", "noise")
HALVES_NOISE_MM = (0.0, 0.5, 1.0)
GIRTHS = ("B", "B1", "C", "D")
#: a halves scan whose girths are more than this off the clean mesh's must say so
OFF_MM = 3.0
#: warnings about the skin that tell the clinic to measure by tape
SAID = ("skin steps", "holds the skin twice", "off the scan's skin")


def read(data: bytes, file_type: str, units: str | None = "mm", side: str | None = None) -> dict:
    """The seam, the girths and the skin warnings of a scan, or its refusal."""
    scan = load_scan(data, file_type=file_type, units=units)
    options = FitOptions(side=side)
    try:
        fit = fit_scan(scan, options, placement=check_scan(scan, options))
    except FitFailure as failure:
        return {"outcome": failure.reason.value}
    record = record_from_fit(fit, scan.source_format, scan.units)
    seam = record.fit.get("skin_seam")
    return {"outcome": "fit", "share": None if seam is None else seam["share"],
            "step_mm": None if seam is None else seam["step_mm"], "moved": bool(seam and seam["moved"]),
            "said": [w for w in record.warnings if any(s in w for s in SAID)],
            "girths": dict(fit.landmarks.tape_girths_mm or {})}


def halves(mesh: trimesh.Trimesh, axis: np.ndarray, noise_mm: float, rng: np.random.Generator) -> tuple[bytes, dict]:
    """A cloud of ``mesh`` (mm) whose points on one side of a plane along ``axis`` moved
    2-6 mm across it (module docstring), and how."""
    n = int(np.clip(mesh.area * rng.uniform(0.25, 0.5), 40_000, 120_000))
    cloud = degrade.sample_cloud(mesh, n, rng)
    move = float(rng.uniform(2.0, 6.0))
    across = np.cross(axis, rng.normal(size=3))
    across /= np.linalg.norm(across)
    normal = np.cross(axis, rng.normal(size=3))
    normal /= np.linalg.norm(normal)
    cloud[(cloud - cloud.mean(axis=0)) @ normal > 0] += move * across
    # the move's share along the cut plane's normal: + opens a gap at the seams, - overlaps
    return as_cloud(degrade.cloud_noise(cloud, noise_mm, rng))[0], {"move_mm": move, "opening": float(across @ normal)}


def facets_cloud(kind: str, seed: int, subject: int, rng: np.random.Generator) -> tuple[bytes, str | None]:
    """100k points drawn by area on the facets of the corpus's ``kind`` mesh (in mm) as a
    PLY cloud, and the side to ask for."""
    case = build_case(CaseSpec(f"seam-{kind}-facets", kind, seed, subject))
    scan = load_scan(case.data, file_type=case.file_type, units=case.units)
    mesh = trimesh.Trimesh(scan.points_mm, scan.faces, process=False)
    return as_cloud(degrade.sample_cloud(mesh, 100_000, rng))[0], case.side


def main(legs: int = 8, seed: int = 43) -> dict:
    rng = np.random.default_rng(seed)
    started = time.perf_counter()
    rows = []
    leg_mesh = trimesh.load(ROOT / "tests" / "data" / "real" / "bodyparts3d_right_leg.stl")
    for _index, noise in enumerate((0.0, 0.0, 0.5, 1.0)):
        cloud = degrade.cloud_noise(degrade.sample_cloud(leg_mesh, int(rng.integers(40_000, 150_000)), rng), noise, rng)
        rows.append({"leg": "bodyparts3d", "kind": f"real_cloud_{noise:g}mm", **read(as_cloud(cloud)[0], "ply")})
        print(rows[-1]["kind"], rows[-1].get("share"), file=sys.stderr)
    subjects = ansur_subjects()
    for leg in range(legs):
        subject = int(rng.integers(len(subjects)))
        for kind in CLOUD_KINDS:
            case = build_case(CaseSpec(f"seam-{leg}-{kind}", kind, int(rng.integers(2**31)), subject))
            side = "right" if kind == "body_vertices" else None  # a body's two legs: one asked for
            rows.append({"leg": leg, "kind": kind, **read(case.data, case.file_type, case.units, side)})
            print(leg, kind, rows[-1].get("share"), file=sys.stderr)
        for kind in FACET_KINDS:
            data, side = facets_cloud(kind, int(rng.integers(2**31)), subject, rng)
            rows.append({"leg": leg, "kind": f"{kind}_facets", **read(data, "ply", "mm", side)})
            print(leg, rows[-1]["kind"], rows[-1].get("share"), file=sys.stderr)
        mesh, axis, _ = clean_leg(int(rng.integers(2**31)), subject)
        clean = read(mesh.export(file_type="stl"), "stl")
        for noise in HALVES_NOISE_MM:
            data, how = halves(mesh, axis, noise, rng)
            got = read(data, "ply")
            errors = {g: got["girths"][g] - clean["girths"][g] for g in GIRTHS
                      if got.get("girths", {}).get(g) and clean.get("girths", {}).get(g)}
            rows.append({"leg": leg, "kind": f"halves_{noise:g}mm", **how, **got, "errors": errors})
            print(leg, rows[-1]["kind"], how, got.get("share"), errors, file=sys.stderr)
    summary = {"legs": legs, "seed": seed, "seconds": time.perf_counter() - started, "environment": environment(),
               "rows": rows}
    stem = "skin_seam" if seed == 43 else f"skin_seam-seed{seed}"
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{stem}.json").write_text(json.dumps(summary, indent=1))
    (RESULTS / f"{stem}.md").write_text(markdown(summary))
    return summary


def markdown(summary: dict) -> str:
    rows = summary["rows"]
    lines = [
        "# A cloud captured in parts while the leg moved (benchmarks/skin_seam.py)", "",
        f"`benchmarks/skin_seam.py {summary['legs']} {summary['seed']}` ({summary['seconds']:.0f} s). "
        + environment_line(summary["environment"]), "",
        f"The seam's share (app.geometry.scan.skin_seam: the slabs whose skin steps along the best path up the calf; "
        f"a seam is said from {SEAM_SHARE:g}); for the halves, |girth - the clean mesh's| over cB, cB1, cC, cD (mm) and "
        f"the scans more than {OFF_MM:g} mm off, with how many of them said so (the seam's warning, the skin twice or the "
        "surface off the skin).", "",
        "| kind | scans | outcomes | share p50 / max | seam said | girth error p50 / max | > 3 mm off | of them said |",
        "|---|---|---|---|---|---|---|---|",
    ]
    by_kind = collections.defaultdict(list)
    for row in rows:
        by_kind[row["kind"]].append(row)
    for kind, group in by_kind.items():
        outcomes = collections.Counter(r["outcome"] for r in group)
        shares = [r["share"] for r in group if r.get("share") is not None]
        share = f"{np.median(shares):.2f} / {max(shares):.2f}" if shares else "not measured"
        unmeasured = sum(r["outcome"] == "fit" and r.get("share") is None for r in group)
        errors = [abs(e) for r in group for e in r.get("errors", {}).values()]
        off = [r for r in group if r.get("errors") and max(abs(e) for e in r["errors"].values()) > OFF_MM]
        lines.append(f"| {kind} | {len(group)} | {', '.join(f'{k} {v}' for k, v in outcomes.items())}"
                     + (f" ({unmeasured} not measured)" if unmeasured and shares else "") + f" | {share} | "
                     f"{sum(r.get('moved', False) for r in group)} | "
                     + (f"{np.median(errors):.1f} / {max(errors):.1f} | {len(off)} | {sum(bool(r['said']) for r in off)}"
                        if errors else "- | - | -") + " |")
    lines += ["", "Halves, per scan:", "", "| leg | kind | move mm | opening | share | step mm | largest girth error | said |",
              "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if not r["kind"].startswith("halves"):
            continue
        worst = max(r.get("errors", {}).items(), key=lambda item: abs(item[1]), default=None)
        lines.append(f"| {r['leg']} | {r['kind']} | {r['move_mm']:.1f} | {r['opening']:+.2f} | "
                     + (f"{r['share']:.2f} | {r['step_mm']:.1f}" if r.get("share") is not None else "- | -") + " | "
                     + (f"c{worst[0]} {worst[1]:+.1f}" if worst else "-") + " | "
                     + ("; ".join(w[:60] for w in r.get("said", [])) or "-") + " |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
