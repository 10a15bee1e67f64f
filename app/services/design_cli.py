"""`calf-nurbs design RECORD.json --class II --stiffness K [--json]`."""

from __future__ import annotations

import argparse
import json

from app.geometry.anatomy import LANDMARK_NAMES as LANDMARKS
from app.records.codec import CalfRecord
from app.services.designs import band_text, compute_design, foot_text, inputs_from_request


def request_from_args(args: argparse.Namespace) -> dict:
    fabric: dict = {}
    if args.table:
        rows = []
        with open(args.table) as handle:
            for line in handle:
                parts = [p for p in line.replace(",", " ").split() if p]
                try:
                    rows.append([float(parts[0]), float(parts[1])])
                except (IndexError, ValueError):
                    continue  # header or blank
        fabric["table"] = rows
    else:
        fabric["stiffness_n_per_cm"] = args.stiffness
        fabric["max_strain"] = args.max_strain
    return {"standard": args.standard, "compression_class": args.compression_class, "fabric": fabric,
            "hot_spot_limit_mmHg": args.hot_spot_limit, "toe": args.toe, "stocking_type": args.type,
            "top_band_mm": args.top_band}


def summary_table(result: dict) -> str:
    lines = []
    cls = result.get("class")
    if cls:
        hi = cls["range_mmHg"][1]
        lines.append(f"{cls['standard']} class {cls['class']} ({cls['range_mmHg'][0]:g}-{hi:g} mmHg at B)" if hi else
                     f"{cls['standard']} class {cls['class']} (>= {cls['range_mmHg'][0]:g} mmHg at B)")
    header = (f"{'':3} {'h mm':>6} {'mean':>6} {'kPa':>5} {'medial':>7} {'lateral':>7} {'anter.':>7} {'poster.':>7} "
              f"{'peak':>6} {'L mm':>6} {'L0 mm':>6} {'strain':>6}")
    lines += [header, "-" * len(header)]
    for name in LANDMARKS:
        lm = result["landmarks"][name]
        s = lm["sides_mmHg"]
        lines.append(f"{name:3} {lm['height_mm']:6.0f} {lm['mean_pressure_mmHg']:6.1f} {lm['mean_pressure_kPa']:5.2f} "
                     f"{s['medial']:7.1f} {s['lateral']:7.1f} {s['anterior']:7.1f} {s['posterior']:7.1f} "
                     f"{lm['peak_pressure_mmHg']:6.1f} {lm['stretched_circumference_mm']:6.0f} "
                     f"{lm['relaxed_circumference_mm']:6.0f} {lm['strain']:6.1%}")
    lines.append("pressures in mmHg (kPa column: mean); L: stretched (hull) circumference; L0: relaxed knitted")
    lines.append("ratios: " + ", ".join(f"{k} {v:.0%}" for k, v in result["ratios"].items()))
    for check in result["checks"]:
        lines.append(f"  [{'pass' if check['pass'] else 'FAIL'}] {check['name']}{'' if check['normative'] else ' (guidance)'}")
    spots = result["hot_spots"]
    lines.append(f"hot spots above {result['hot_spot_limit_mmHg']:g} mmHg: {len(spots)}")
    for spot in spots[:5]:
        lines.append(f"  {spot['peak_mmHg']:.0f} mmHg at {spot['height_mm']:.0f} mm, {spot['side']} ({spot['angle_deg']:.0f} deg)")
    if result.get("thigh"):
        lines.append("thigh-high (AG), on the thigh's tape girths (mean pressure):")
        for name, level in result["thigh"]["levels"].items():
            lines.append(f"{name:3} {level['height_mm']:6.0f} {level['mean_pressure_mmHg']:6.1f} "
                         f"(target {level['target_mmHg']:.1f})  L {level['stretched_circumference_mm']:6.0f}  "
                         f"L0 {level['relaxed_circumference_mm']:6.0f}  strain {level['strain']:6.1%}")
    for row in (r for r in result["knitting_spec"] if r.get("part") == "foot"):
        lines.append(f"foot {row['point']:3} {row['predicted_mean_mmHg']:6.1f} mmHg  L {row['stretched_circumference_mm']:6.0f}  "
                     f"L0 {row['relaxed_circumference_mm']:6.0f}  strain {row['strain']:6.1%}")
    lines.append(f"foot: {foot_text(result.get('foot'))}")
    lines.append(f"top band: {band_text(result.get('top_band'))}")
    lines.append(f"verdict: {result['verdict']}" + "".join(f"\n  - {r}" for r in result.get("verdict_reasons") or []))
    if result["side_assumed"]:
        lines.append("side unknown: medial/lateral assume a right leg")
    return "\n".join(lines)


def run_design_cli(record: CalfRecord, args: argparse.Namespace) -> int:
    request = request_from_args(args)
    result = compute_design(record, inputs_from_request(request))
    if args.json:
        print(json.dumps({"inputs": request, **result}, indent=2))
    else:
        print(summary_table(result))
    return 0
