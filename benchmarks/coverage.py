"""A leg the scanner did not see all round: what the service answers.

Run:  .venv/bin/python benchmarks/coverage.py [LEGS] [SEED]   (default 20 23)
      .venv/bin/python benchmarks/coverage.py --rewrite [SEED]   (the md from the JSON)
Writes benchmarks/results/coverage.md and coverage.json; with another seed than the
default 23 (a hold-out), coverage-seedN.md and coverage-seedN.json.

Each of LEGS generated whole legs (an ANSUR II subject's MakeHuman leg with its foot,
benchmarks/corpus, in millimetres) is scanned clean as a mesh - the reference - and again
as each of :data:`KINDS`, every scan checked and fitted as an upload is:

- ``strip_mesh`` / ``strip_cloud``: a strip along the whole leg is missing, of a random
  width (:data:`STRIP_DEG`) round the leg's own axis and in a random direction (a
  scanner's blind side, the inner leg a standing body scanner does not see): the skin
  whose angle about its 10 mm slab's centre lies in the strip is removed (a mesh loses
  every triangle touching it);
- ``view_mesh`` / ``view_cloud``: one depth camera's view from a random direction across
  the leg: the skin whose normal faces the camera by more than 10 degrees (a sensor
  loses grazing skin) - the leg seen from one side;
- ``two_views_cloud``: two such views from opposite sides merged (front and back): a
  sliver lost at each grazing side.

A scan is answered right when it is refused as ``partial_view``, or fitted with every
girth (cB, cB1, cC, cD) within :data:`OFF_MM` of the clean mesh's, or fitted with a
warning that the skin misses an arc or the surface stands off it.  Anything else - a
fit more than OFF_MM off without a word, a refusal naming an ankle, calf or knee the
scan holds - is wrong, and listed.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.corpus import degrade  # noqa: E402
from benchmarks.corpus.makehuman import ansur_subjects  # noqa: E402
from benchmarks.motion import as_cloud, clean_leg, kind_summary, read  # noqa: E402
from benchmarks.provenance import environment, environment_line  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
GIRTHS = ("cB", "cB1", "cC", "cD")
KINDS = ("strip_mesh", "strip_cloud", "view_mesh", "view_cloud", "two_views_cloud")
#: a missing strip's width, degrees round the leg
STRIP_DEG = (20.0, 160.0)
#: a depth camera keeps the skin whose normal faces it by more than this, degrees
GRAZING_DEG = 10.0
#: what a warning about missing skin says
SAID = ("misses an arc", "off the scan's skin")
OFF_MM = 3.0


def _angle_about_axis(points: np.ndarray, axis: np.ndarray, across: np.ndarray) -> np.ndarray:
    """(n,) each point's angle (radians) round ``axis`` about its 10 mm slab's centroid,
    from ``across`` (unit, perpendicular to the axis)."""
    height = points @ axis
    slab = np.floor((height - height.min()) / 10.0).astype(np.int64)
    count = np.bincount(slab)
    centre = np.stack([np.bincount(slab, points[:, i]) for i in range(3)], axis=1) / np.maximum(count, 1)[:, None]
    rel = points - centre[slab]
    other = np.cross(axis, across)
    return np.arctan2(rel @ other, rel @ across)


def incomplete_scans(mesh: trimesh.Trimesh, axis: np.ndarray, rng: np.random.Generator) -> dict:
    """kind -> (bytes, file type, what is missing in words) of the leg ``mesh`` (mm)."""
    out = {}
    for kind in KINDS:
        across = np.cross(axis, rng.normal(size=3))
        across /= np.linalg.norm(across)
        n = int(np.clip(mesh.area * rng.uniform(0.25, 0.5), 40_000, 120_000))
        if kind.startswith("strip"):
            width = float(rng.uniform(*STRIP_DEG))
            what = f"strip {width:.0f} deg"
            if kind == "strip_mesh":
                gone = np.abs(_angle_about_axis(mesh.vertices, axis, across)) < np.radians(width / 2)
                strip = mesh.copy()
                strip.update_faces(~gone[strip.faces].any(axis=1))
                strip.remove_unreferenced_vertices()
                out[kind] = (strip.export(file_type="stl"), "stl", what)
            else:
                cloud = degrade.sample_cloud(mesh, n, rng)
                keep = np.abs(_angle_about_axis(cloud, axis, across)) >= np.radians(width / 2)
                out[kind] = (*as_cloud(cloud[keep]), what)
            continue
        facing = np.cos(np.radians(90.0 - GRAZING_DEG))
        views = (across, -across) if kind == "two_views_cloud" else (across,)
        if kind == "view_mesh":
            seen = mesh.copy()
            seen.update_faces(mesh.face_normals @ across > facing)  # normals towards the camera at +across
            seen.remove_unreferenced_vertices()
            out[kind] = (seen.export(file_type="stl"), "stl", "one view")
            continue
        points, face = trimesh.sample.sample_surface(mesh, n, seed=int(rng.integers(2**31)))
        normals = mesh.face_normals[face]
        keep = np.zeros(len(points), dtype=bool)
        for camera in views:
            keep |= normals @ camera > facing
        out[kind] = (*as_cloud(np.asarray(points)[keep]), f"{len(views)} view(s)")
    return out


def judged(got: dict, clean: dict) -> dict:
    """The scan's answer against the clean mesh's (module docstring)."""
    if got["outcome"] != "fit":
        return {"right": got["outcome"] == "partial_view", "errors": {}, "said": []}
    errors = {g: got[g] - clean[g] for g in GIRTHS if got.get(g) is not None and clean.get(g) is not None}
    said = [w for w in got.get("warnings", []) if any(s in w for s in SAID)]
    off = bool(errors) and max(abs(e) for e in errors.values()) > OFF_MM
    return {"right": not off or bool(said), "errors": errors, "said": said}


def leg_scans(legs: int, seed: int):
    """Each of ``legs`` generated legs (mm) with its incomplete scans (:func:`incomplete_scans`),
    drawn from ``seed``: (leg index, clean mesh, scans).  A leg's scans are drawn whether or
    not its clean mesh fits, so a leg's scans do not depend on how the fit of another went."""
    rng = np.random.default_rng(seed)
    for leg in range(legs):
        mesh, axis, _ = clean_leg(int(rng.integers(2**31)), int(rng.integers(len(ansur_subjects()))))
        yield leg, mesh, incomplete_scans(mesh, axis, rng)


def main(legs: int = 20, seed: int = 23) -> dict:
    started = time.perf_counter()
    rows = []
    for leg, mesh, scans in leg_scans(legs, seed):
        clean = read(mesh.export(file_type="stl"), "stl")
        if clean["outcome"] != "fit":
            rows.append({"leg": leg, "kind": "mesh_clean", "what": "-", "outcome": clean["outcome"],
                         "detail": clean.get("detail"), "right": False, "errors": {}, "said": []})
            continue
        for kind, (data, file_type, what) in scans.items():
            got = read(data, file_type)
            verdict = judged(got, clean)
            rows.append({"leg": leg, "kind": kind, "what": what, "outcome": got["outcome"], "detail": got.get("detail"),
                         **verdict})
            print(f"leg {leg} {kind} {what}: {got['outcome']} "
                  + " ".join(f"{g}{e:+.1f}" for g, e in verdict["errors"].items())
                  + f" said {len(verdict['said'])} {'ok' if verdict['right'] else 'WRONG'}", file=sys.stderr)
    summary = {"environment": environment(), "legs": legs, "seed": seed, "seconds": time.perf_counter() - started,
               "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{_stem(seed)}.json").write_text(json.dumps(summary, indent=1))
    write(summary)
    return summary


def _stem(seed: int) -> str:
    """The results' file name: coverage for the default seed, coverage-seedN for a hold-out."""
    return "coverage" if seed == 23 else f"coverage-seed{seed}"


def _strip_width(row: dict) -> float | None:
    return float(row["what"].split()[1]) if row["what"].startswith("strip") else None


def write(summary: dict) -> None:
    lines = [
        "# A leg the scanner did not see all round (benchmarks/coverage.py)",
        "",
        f"{summary['legs']} generated whole legs (seed {summary['seed']}), each scanned clean as a mesh (the reference) "
        f"and as each kind below; {summary['seconds']:.0f} s.  Right: refused as partial_view, or fitted with cB, cB1, "
        f"cC, cD within {OFF_MM:g} mm of the clean mesh's, or fitted with a warning that the skin misses an arc or "
        "the surface stands off it.",
        "",
        environment_line(summary.get("environment")),
        "",
        "| kind | strip width deg | scans | outcomes | fitted: girths p50 / p95 / max mm | fitted > 3 mm off | of them "
        "warned | right |",
        "|---|---|---|---|---|---|---|---|",
    ]
    bands = {"strip_mesh": ((20, 60), (60, 100), (100, 160)), "strip_cloud": ((20, 60), (60, 100), (100, 160))}
    for kind in KINDS:
        for band in bands.get(kind, (None,)):
            rows = [r for r in summary["rows"] if r["kind"] == kind
                    and (band is None or band[0] <= (_strip_width(r) or 0) < band[1])]
            if not rows:
                continue
            outcomes, stats, off = kind_summary(rows, OFF_MM)
            lines.append(f"| {kind} | {'-' if band is None else f'{band[0]}-{band[1]}'} | {len(rows)} | {outcomes}"
                         f" | {stats} | {len(off)} | {sum(bool(r['said']) for r in off)} | "
                         f"{sum(r['right'] for r in rows)} of {len(rows)} |")
    wrong = [r for r in summary["rows"] if not r["right"]]
    lines += ["", f"Answered wrong ({len(wrong)}):", ""]
    for r in wrong:
        worst = max(r["errors"].items(), key=lambda item: abs(item[1]), default=None)
        lines.append(f"- leg {r['leg']} {r['kind']} ({r['what']}): {r['outcome']}"
                     + (f", {worst[0]} {worst[1]:+.1f} mm, no warning" if worst else f" ({(r['detail'] or '')[:110]})"))
    (RESULTS / f"{_stem(summary['seed'])}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--rewrite"]:
        write(json.loads((RESULTS / f"{_stem(int(sys.argv[2]) if len(sys.argv) > 2 else 23)}.json").read_text()))
    else:
        main(*(int(a) for a in sys.argv[1:3]))
