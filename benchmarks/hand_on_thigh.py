"""A hand held against the thigh: are cF and cG read round it?
(app.geometry.anatomy.thigh_contact)

Run:  .venv/bin/python benchmarks/hand_on_thigh.py [LEGS] [SEED]   (default 8 21)
Writes benchmarks/results/hand_on_thigh.md and hand_on_thigh.json (hand_on_thigh-seedN.*
for another seed).

Each of LEGS generated legs (an ANSUR II subject's MakeHuman leg, foot to hip,
benchmarks/corpus, mm) is scanned bare as a mesh (STL) and as a noisy cloud (80k points,
0.5 mm noise), then as that cloud with a hand against its thigh: an ellipsoid 25-35 mm
thick, 170-200 mm long and 75-90 mm wide (an adult hand's thickness at the metacarpals,
length and breadth),
its palm on the skin at the leg's outer side turned -45..45 degrees towards the front or
back, its fingertips 40 mm under F, 30 mm over F, 60 mm under G (the hand covers G), or 20
or 50 mm over G (it does not); the skin under the hand is hidden, as a scanner sees it.
A scanner fuses a touching hand into the leg's mesh; a cloud shows it as one surface too
(a mesh of the hand as its own shell is set aside as a detached piece).

Right: bare, cF and cG measured (or not, as the bare mesh); with a hand covering G, cF
and cG not measured (with the contact's reason, or another); with a hand over G, cF and
cG within TOLERANCE_MM of the bare cloud's.  Wrong: a bare leg said to have something
against it; a cF or cG read with a hand under its tape, or moved by one above it.
"""

from __future__ import annotations

import collections
import io
import json
import sys
import time
from pathlib import Path

import numpy as np
import trimesh

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from app.geometry.errors import FitFailure  # noqa: E402
from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from app.records.codec import record_from_fit  # noqa: E402
from benchmarks.corpus import degrade  # noqa: E402
from benchmarks.corpus.makehuman import ansur_subjects, leg_submesh, sized_legs  # noqa: E402
from benchmarks.provenance import environment, environment_line  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
#: a point measured with a hand above its tape: right within this of the bare cloud's (mm)
TOLERANCE_MM = 3.0
#: how a record says that F and G were not measured for something against the thigh
#: (app.geometry.anatomy.thigh_contact.ThighContact.reason: an arc at the outer or inner
#: side, a garment's hem)
CONTACT_SAID = ("something lies against", "the thigh is covered")
#: where the fingertips are: (name, the point, mm from it, does the hand cover G)
HANDS = (("F-40", "F", -40.0, True), ("F+30", "F", 30.0, True), ("G-60", "G", -60.0, True),
         ("G+20", "G", 20.0, False), ("G+50", "G", 50.0, False))


def _fit(data: bytes, file_type: str, side: str) -> dict:
    scan = load_scan(data, file_type=file_type)
    options = FitOptions(side=side)
    try:
        fit = fit_scan(scan, options, placement=check_scan(scan, options))
    except FitFailure as failure:
        return {"refused": failure.reason.value}
    return record_from_fit(fit, scan.source_format, scan.units).to_dict()


def _xyz(points: np.ndarray) -> bytes:
    text = io.StringIO()
    np.savetxt(text, points, fmt="%.3f")
    return text.getvalue().encode()


def _thigh(record: dict) -> dict:
    """cF and cG of a record: value (mm) or "contact" / "none" (not measured, for
    something against or round the thigh - a hand, a garment - or another reason) or the
    refusal."""
    if "refused" in record:
        return {"refused": record["refused"]}
    out = {}
    for name in ("cF", "cG"):
        point = record["chart"][name]
        out[name] = (round(point["value_mm"], 2) if point.get("value_mm") is not None else
                     "contact" if any(said in (point.get("reason") or "") for said in CONTACT_SAID) else "none")
    return out


def _with_hand(leg: trimesh.Trimesh, cloud: np.ndarray, tip_y: float, sign: float,
               rng: np.random.Generator) -> tuple[np.ndarray, dict]:
    """``cloud`` (n, 3) of ``leg`` (MakeHuman mm, standing along +y; ``sign`` +1 its
    left leg, x > 0) with a hand against its outer side from ``tip_y`` up: the cloud
    and the hand's notes."""
    thick, length, width = rng.uniform(25, 35), rng.uniform(170, 200), rng.uniform(75, 90)
    turn = np.radians(rng.uniform(-45, 45))
    centre_y = tip_y + length / 2
    # the palm rests where its middle is, or (a hand over G reaching past the scan's top,
    # which ends at the hip) on the scan's last 10 mm
    rest_y = min(centre_y, float(leg.vertices[:, 1].max()) - 10.0)
    near = leg.vertices[np.abs(leg.vertices[:, 1] - rest_y) < 5.0]
    out = np.array([sign * np.cos(turn), 0.0, np.sin(turn)])  # the palm's normal, away from the leg
    middle = near.mean(axis=0)
    centre = middle + (((near - middle) @ out).max() + thick / 2) * out
    centre[1] = centre_y
    axes = np.column_stack([out, [0.0, 1.0, 0.0], np.cross(out, [0.0, 1.0, 0.0])])  # thickness, length, width
    hand = trimesh.creation.icosphere(subdivisions=3)
    hand.apply_scale([thick / 2, length / 2, width / 2])
    placed = np.eye(4)
    placed[:3, :3], placed[:3, 3] = axes, centre
    hand.apply_transform(placed)
    hand_points = degrade.cloud_noise(degrade.sample_cloud(hand, 6000, rng), 0.5, rng)
    covered = ((((cloud - centre) @ axes) / (np.array([thick, length, width]) / 2 + 3.0)) ** 2).sum(axis=1) < 1.0
    palm = (hand_points - centre) @ out < -thick / 2 + 5.0  # the palm on the skin: not seen
    notes = {"thick_mm": round(thick, 1), "length_mm": round(length, 1), "width_mm": round(width, 1),
             "turn_deg": round(float(np.degrees(turn)), 1)}
    return np.vstack([cloud[~covered], hand_points[~palm]]), notes


def _verdict(bare: dict, held: dict, covers_g: bool) -> str:
    if "refused" in held:
        return f"refused {held['refused']}"
    if covers_g:
        if all(isinstance(held[k], str) for k in ("cF", "cG")):
            return "not measured: contact" if held["cG"] == "contact" else "not measured: other reason"
        return "WRONG: read round the hand"
    both = [k for k in ("cF", "cG") if not isinstance(held[k], str) and not isinstance(bare.get(k, ""), str)]
    if len(both) < 2 and any(not isinstance(bare.get(k, ""), str) for k in ("cF", "cG")):
        return "not measured: contact" if "contact" in held.values() else "not measured: other reason"
    if not both:
        return "not measured, as the bare cloud"
    off = max(abs(held[k] - bare[k]) for k in both)
    return "right" if off <= TOLERANCE_MM else f"WRONG: {off:.0f} mm off"


def generated_thighs(legs: int, rng: np.random.Generator):
    """(index, leg mesh, sign, side, bare cloud) for ``legs`` generated legs drawn from
    ``rng`` in turn: an ANSUR II subject's MakeHuman leg, foot to hip (MakeHuman mm,
    standing along +y; ``sign`` +1 its left leg), and its noisy cloud (80k points, 0.5 mm
    noise).  The caller may draw from ``rng`` between legs (benchmarks/garment_on_thigh.py
    reads its legs this way too)."""
    subjects = ansur_subjects()
    for index in range(legs):
        generated = sized_legs(subjects[int(rng.integers(len(subjects)))], rng, subdivisions=2)
        sign = float(rng.choice([1.0, -1.0]))
        leg = leg_submesh(generated.vertices, generated.faces, sign)
        cloud = degrade.cloud_noise(degrade.sample_cloud(leg, 80_000, rng), 0.5, rng)
        yield index, leg, sign, "left" if sign > 0 else "right", cloud


def write_results(stem: str, title: str, run: str, started: float, rows: list[dict], tally: collections.Counter,
                  head: list[str], cells: list[list[str]]) -> None:
    """``stem``.json (the run, its rows and tally) and ``stem``.md (``title``; the
    command ``run``, how long since ``started`` and the environment; the tally; a table
    of ``head`` columns and a row of ``cells`` per leg) in benchmarks/results."""
    env = environment()
    legs, seed = (int(a) for a in run.split()[-2:])
    (RESULTS / f"{stem}.json").write_text(json.dumps(
        {"environment": env, "legs": legs, "seed": seed, "rows": rows,
         "tally": {f"{k[0]} | {k[1]}": v for k, v in sorted(tally.items())}}, indent=1))
    lines = [f"# {title}", "",
             f"`{run}` ({time.perf_counter() - started:.0f} s). " + environment_line(env), "",
             "| scan | answer | cases |", "|---|---|---|",
             *(f"| {k[0]} | {k[1]} | {v} |" for k, v in sorted(tally.items())), "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head),
             *("| " + " | ".join(row) + " |" for row in cells)]
    (RESULTS / f"{stem}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def main(legs: int = 8, seed: int = 21) -> dict:
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    rows, tally = [], collections.Counter()
    for index, leg, sign, side, cloud in generated_thighs(legs, rng):
        mesh_record, cloud_record = _fit(leg.export(file_type="stl"), "stl", side), _fit(_xyz(cloud), "xyz", side)
        bare = {"mesh": _thigh(mesh_record), "cloud": _thigh(cloud_record)}
        for kind, read in bare.items():
            verdict = "WRONG: contact on a bare leg" if "contact" in read.values() else "right"
            tally[(f"bare {kind}", verdict)] += 1
        row = {"leg": index, "side": side, "bare": bare, "hands": []}
        placed = next((r for r in (mesh_record, cloud_record) if "refused" not in r
                       and r["chart"]["cG"].get("at_mm") is not None), None)
        if placed is None:
            rows.append(row)
            continue
        frame = np.asarray(placed["frame"])  # calf frame -> scan (= generating) mm
        at_y = {name: float((frame @ np.r_[placed["chart"][f"c{name}"]["at_mm"], 1.0])[1]) for name in ("F", "G")}
        for name, point, offset, covers_g in HANDS:
            held_cloud, notes = _with_hand(leg, cloud, at_y[point] + offset, sign, rng)
            held = _thigh(_fit(_xyz(held_cloud), "xyz", side))
            verdict = _verdict(bare["cloud"], held, covers_g)
            tally[(f"hand {name}", verdict)] += 1
            row["hands"].append({"fingertips": name, **notes, "read": held, "verdict": verdict})
        rows.append(row)
        print(f"leg {index} {side}: bare {bare}; " + "; ".join(f"{h['fingertips']} {h['verdict']}" for h in row["hands"]),
              file=sys.stderr)
    cells = [[str(row["leg"]), row["side"], str(row["bare"]["mesh"]), str(row["bare"]["cloud"]),
              *([f"{h['read'].get('cF', h['read'].get('refused'))}, {h['read'].get('cG', '')}: {h['verdict']}"
                 for h in row["hands"]] or ["no G on the bare leg"] * len(HANDS))] for row in rows]
    write_results("hand_on_thigh" + ("" if seed == 21 else f"-seed{seed}"),
                  "A hand against the thigh (benchmarks/hand_on_thigh.py)",
                  f"benchmarks/hand_on_thigh.py {legs} {seed}", started, rows, tally,
                  ["leg", "side", "bare mesh cF, cG", "bare cloud cF, cG", *(h[0] for h in HANDS)], cells)
    return {"tally": tally}


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
