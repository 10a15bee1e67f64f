"""Where a benchmark's numbers come from: the commit and the numerical libraries' versions.

The project's dependencies are lower bounds (pyproject.toml): a fresh ``make install``
takes the newest release the package index serves.  The same commit (8db9cdd) gave seed
7's corpus girths up to 1.05 mm apart on a noisy cloud (cB1; 0.28 mm on a mesh) and other
warnings on 10 of its 218 cases (a floor's point count, the surface's stand-off, the
knee's and the fold's), run in two sessions' virtual environments
(benchmarks/robustness.py 220 7, 2026-12-06); within one environment two runs agree case
by case, under different loads, and numpy was 2.4.6 in both, so the other libraries'
releases are the likely cause - the earlier run did not record them.  A
result is comparable across sessions only with its environment, which the results now
carry.
"""

from __future__ import annotations

import platform
import subprocess
from importlib import metadata
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: the libraries whose arithmetic the geometry core's numbers depend on
NUMERICAL = ("numpy", "scipy", "scikit-learn", "trimesh")


def _git(*args: str) -> str:
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def environment() -> dict:
    """{"commit": short hash (+ "-dirty" when the code in app/ or benchmarks/ differs from it,
    results aside; "" outside a git checkout), "python": version, and each of :data:`NUMERICAL`: its version}."""
    commit = _git("rev-parse", "--short", "HEAD")
    if commit and _git("status", "--porcelain", "--", "app", "benchmarks", ":(exclude)benchmarks/results"):
        commit += "-dirty"
    versions = {}
    for name in NUMERICAL:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = "not installed"
    return {"commit": commit, "python": platform.python_version(), **versions}


def environment_line(env: dict | None) -> str:
    """The environment in one line of a results page (or that the run did not record it)."""
    if not env:
        return "Environment: not recorded (a run before benchmarks/provenance.py)."
    libraries = ", ".join(f"{name} {env.get(name, '?')}" for name in NUMERICAL)
    return f"Environment: commit {env.get('commit') or '?'}, Python {env.get('python', '?')}, {libraries}."
