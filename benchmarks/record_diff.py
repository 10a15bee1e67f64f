"""Did a change move any number of a record?  Dump the records of the real legs (both
modes) and of a slice of the generated corpus, then compare two dumps value by value.

Run:  .venv/bin/python benchmarks/record_diff.py dump before.json      (on the old commit)
      .venv/bin/python benchmarks/record_diff.py dump after.json       (on the new one)
      .venv/bin/python benchmarks/record_diff.py compare before.json after.json

``dump`` fits the 5 real legs (tests/data/real) in paper and lsq mode and every other of
the 62 specs of ``corpus_specs(60, seed=7)`` as an upload is (check, then fit with the
check's placement) and writes each record's JSON (or its failure's reason).  ``compare``
prints, per record, every value that differs by more than 1e-9 relative (issue 21's bar
for a change that must not move the numbers), a key present on one side only, and a
changed string; timings are left out.  Exit 1 when anything differs.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

REAL = Path(__file__).resolve().parents[1] / "tests" / "data" / "real"
REAL_LEGS = [("bodyparts3d_right_leg.stl", None), ("vh_male_skin.glb", "left"), ("vh_male_skin.glb", "right"),
             ("vh_female_skin.glb", "left"), ("vh_female_skin.glb", "right")]
#: keys whose values are wall time, not results
TIMING_KEYS = ("seconds", "stage_seconds")
RELATIVE_TOLERANCE = 1e-9


def dump(path: str) -> None:
    from app.geometry.errors import FitFailure
    from app.geometry.fit.pipeline import FitOptions, check_scan, fit_scan
    from app.geometry.scan.reader import load_scan
    from app.records.codec import record_from_fit
    from benchmarks.corpus.cases import build_case, corpus_specs

    records: dict = {}
    for file, side in REAL_LEGS:
        for mode in ("paper", "lsq"):
            scan = load_scan(REAL / file)
            options = FitOptions(side=side, mode=mode)
            fit = fit_scan(scan, options, placement=check_scan(scan, options))
            records[f"{file}/{side}/{mode}"] = record_from_fit(fit, scan.source_format, scan.units).to_dict()
    for spec in corpus_specs(60, seed=7)[::2]:
        case = build_case(spec)
        try:
            scan = load_scan(case.data, file_type=case.file_type, units=case.units)
            options = FitOptions(side=case.side)
            fit = fit_scan(scan, options, placement=check_scan(scan, options))
            records[spec.case_id] = record_from_fit(fit, scan.source_format, scan.units).to_dict()
        except FitFailure as failure:
            records[spec.case_id] = {"failure": failure.reason.value}
    Path(path).write_text(json.dumps(records, default=str))
    print(f"{len(records)} records -> {path}")


def differences(a, b, where: str = "") -> list[tuple[str, str]]:
    """(path, what) of every difference between two JSON values (module docstring)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in sorted(set(a) | set(b)):
            if key in TIMING_KEYS:
                continue
            if key not in a or key not in b:
                out.append((f"{where}/{key}", "only in " + ("the second" if key not in a else "the first")))
            else:
                out += differences(a[key], b[key], f"{where}/{key}")
        return out
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return [(where, f"length {len(a)} -> {len(b)}")]
        return [d for i, (x, y) in enumerate(zip(a, b)) for d in differences(x, y, f"{where}[{i}]")]
    numbers = (int, float)
    if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool) and not isinstance(b, bool):
        if a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)):
            return []
        relative = abs(a - b) / max(abs(a), abs(b))
        return [] if relative <= RELATIVE_TOLERANCE else [(where, f"{a!r} -> {b!r} ({relative:.1e} relative)")]
    return [] if a == b else [(where, f"{str(a)[:60]!r} -> {str(b)[:60]!r}")]


def compare(first: str, second: str) -> int:
    a, b = json.loads(Path(first).read_text()), json.loads(Path(second).read_text())
    changed = 0
    for name in sorted(set(a) | set(b)):
        found = differences(a.get(name), b.get(name))
        if found:
            changed += 1
            print(f"{name}: {len(found)} difference(s)")
            for where, what in found[:12]:
                print(f"    {where}: {what}")
    print(f"{changed} of {len(set(a) | set(b))} records differ")
    return 1 if changed else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "dump":
        dump(sys.argv[2])
    elif len(sys.argv) == 4 and sys.argv[1] == "compare":
        sys.exit(compare(sys.argv[2], sys.argv[3]))
    else:
        sys.exit(__doc__)
