"""A garment's leg round the thigh - shorts or a trouser leg hanging loose: are cF and cG
read on the garment? (app.geometry.anatomy.thigh_contact's hem rule)

Run:  .venv/bin/python benchmarks/garment_on_thigh.py [LEGS] [SEED]   (default 8 23)
Writes benchmarks/results/garment_on_thigh.md and garment_on_thigh.json
(garment_on_thigh-seedN.* for another seed).

Each of LEGS generated legs (an ANSUR II subject's MakeHuman leg, foot to hip,
benchmarks/corpus, mm) is scanned bare as a noisy cloud (80k points, 0.5 mm noise, as
benchmarks/hand_on_thigh.py does), then in loose shorts: from the hem up the skin is
hidden under a tube of fabric OFFSETS_MM off it, hanging straight down from the widest
skin above (a loose garment does not follow the thigh's taper nor the gluteal fold), the
hem a ring from the skin out to the fabric, sampled as densely as the leg (a point every
2 mm by 2 degrees, 0.5 mm noise).  The hem is 30 mm under F, 40 mm over F, 40 mm under G
(all three cover G) or 20 mm over G (it does not, though it lies in the tape's reach).

Right: with the hem under G, cF and cG not measured (for the garment, or another reason);
with it over G, cF and cG within TOLERANCE_MM of the bare cloud's, or not measured as the
bare cloud's are.  Wrong: a girth read on the garment, or moved by it.
"""

from __future__ import annotations

import collections
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.corpus import degrade  # noqa: E402
from benchmarks.hand_on_thigh import TOLERANCE_MM, _fit, _thigh, _xyz, generated_thighs, write_results  # noqa: E402

#: where the hem is: (name, the point, mm from it, does the garment cover G)
HEMS = (("F-30", "F", -30.0, True), ("F+40", "F", 40.0, True), ("G-40", "G", -40.0, True),
        ("G+20", "G", 20.0, False))
#: how far the fabric hangs off the widest skin above it, mm
OFFSETS_MM = (5.0, 10.0, 20.0)
#: the fabric's sampling: a point every GRID_MM of height and GRID_DEG round
GRID_MM, GRID_DEG = 2.0, 2.0


def in_shorts(cloud: np.ndarray, hem_y: float, offset_mm: float, axis_xz: np.ndarray,
              rng: np.random.Generator) -> np.ndarray:
    """``cloud`` (n, 3), MakeHuman mm standing along +y, with the skin from ``hem_y`` up
    hidden under a loose garment ``offset_mm`` off it, round the vertical axis through
    ``axis_xz`` (2,): at each angle the fabric lies ``offset_mm`` out from the widest
    skin at or above that height (it hangs straight down), and the hem is a ring from the
    skin out to the fabric.  Returns the scan's cloud (m, 3)."""
    above = cloud[:, 1] >= hem_y
    heights = np.arange(hem_y, cloud[:, 1].max(), GRID_MM)
    angles = np.radians(np.arange(-180.0, 180.0, GRID_DEG))
    relative = cloud[above][:, [0, 2]] - axis_xz
    row = np.clip(((cloud[above, 1] - hem_y) // GRID_MM).astype(np.int64), 0, len(heights) - 1)
    column = (((np.arctan2(relative[:, 1], relative[:, 0]) + np.pi) // np.radians(GRID_DEG)).astype(np.int64)
              % len(angles))
    skin = np.full((len(heights), len(angles)), np.nan)
    np.fmax.at(skin, (row, column), np.hypot(relative[:, 0], relative[:, 1]))
    for _ in range(3):  # a cell without a point takes its neighbours' round the section
        skin = np.where(np.isnan(skin), np.fmax(np.roll(skin, 1, axis=1), np.roll(skin, -1, axis=1)), skin)
    fabric = np.fmax.accumulate(skin[::-1], axis=0)[::-1] + offset_mm  # widest skin above, plus the offset
    height, angle = np.meshgrid(heights, angles, indexing="ij")
    # the hem: six rings from the skin out to the fabric at the hem's height
    share = np.linspace(0.0, 1.0, 6)[:, None]
    hem_r = skin[0][None, :] + share * (fabric[0] - skin[0])[None, :]
    radius = np.vstack([fabric, hem_r])
    height = np.vstack([height, np.full(hem_r.shape, hem_y)])
    angle = np.vstack([angle, np.broadcast_to(angles, hem_r.shape)])
    seen = np.isfinite(radius)
    garment = np.column_stack([axis_xz[0] + radius[seen] * np.cos(angle[seen]), height[seen],
                               axis_xz[1] + radius[seen] * np.sin(angle[seen])])
    return np.vstack([cloud[~above], degrade.cloud_noise(garment, 0.5, rng)])


def _verdict(bare: dict, worn: dict, covers_g: bool) -> str:
    if "refused" in worn:
        return f"refused {worn['refused']}"
    if covers_g:
        if all(isinstance(worn[k], str) for k in ("cF", "cG")):
            return "not measured: garment" if worn["cG"] == "contact" else "not measured: other reason"
        return "WRONG: read on the garment"
    both = [k for k in ("cF", "cG") if not isinstance(worn[k], str) and not isinstance(bare.get(k, ""), str)]
    if not both:
        return ("not measured, as the bare cloud" if all(isinstance(bare.get(k, ""), str) for k in ("cF", "cG"))
                else "not measured: garment" if "contact" in worn.values() else "not measured: other reason")
    off = max(abs(worn[k] - bare[k]) for k in both)
    return "right" if off <= TOLERANCE_MM else f"WRONG: {off:.0f} mm off"


def main(legs: int = 8, seed: int = 23) -> dict:
    started = time.perf_counter()
    rng = np.random.default_rng(seed)
    rows, tally = [], collections.Counter()
    for index, _leg, _sign, side, cloud in generated_thighs(legs, rng):
        record = _fit(_xyz(cloud), "xyz", side)
        bare = _thigh(record)
        tally[("bare cloud", "WRONG: garment on a bare leg" if "contact" in bare.values() else "right")] += 1
        row = {"leg": index, "side": side, "bare": bare, "garments": []}
        if "refused" in record or record["chart"]["cG"].get("at_mm") is None:
            rows.append(row)
            continue
        frame = np.asarray(record["frame"])  # calf frame -> scan (= generating) mm
        at = {name: frame @ np.r_[record["chart"][f"c{name}"]["at_mm"], 1.0] for name in ("F", "G")}
        axis_xz = at["F"][[0, 2]]
        for name, point, shift, covers_g in HEMS:
            for offset in OFFSETS_MM:
                worn = _thigh(_fit(_xyz(in_shorts(cloud, float(at[point][1] + shift), offset, axis_xz, rng)), "xyz", side))
                verdict = _verdict(bare, worn, covers_g)
                tally[(f"hem {name}, {offset:.0f} mm loose", verdict)] += 1
                row["garments"].append({"hem": name, "offset_mm": offset, "read": worn, "verdict": verdict})
        rows.append(row)
        print(f"leg {index} {side}: bare {bare}; "
              + "; ".join(f"{g['hem']}/{g['offset_mm']:.0f} {g['verdict']}" for g in row["garments"]), file=sys.stderr)
    cases = [f"{h[0]}/{o:.0f}" for h in HEMS for o in OFFSETS_MM]
    cells = [[str(row["leg"]), row["side"], str(row["bare"]),
              *([f"{g['read'].get('cF', g['read'].get('refused'))}, {g['read'].get('cG', '')}: {g['verdict']}"
                 for g in row["garments"]] or ["no G on the bare leg"] * len(cases))] for row in rows]
    write_results("garment_on_thigh" + ("" if seed == 23 else f"-seed{seed}"),
                  "A garment's leg round the thigh (benchmarks/garment_on_thigh.py)",
                  f"benchmarks/garment_on_thigh.py {legs} {seed}", started, rows, tally,
                  ["leg", "side", "bare cloud cF, cG", *cases], cells)
    return {"tally": tally}


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
