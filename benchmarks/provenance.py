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

The versions are not the whole environment.  Seed 13's corpus, run at 4cf8cb8 and at
24806a9 with the same numpy, scipy, scikit-learn and trimesh (2.4.6, 1.17.1, 1.9.1,
5.2.0) in two sessions, read cloud and noisy-mesh girths up to 0.8 mm apart (noise-02's
cB +0.29 and -0.51 mm), where 24806a9's change touches no cloud; run twice in one
session across that change, seed 17's clouds agree case by case.  The machine is the
next suspect: the BLAS the wheels bundle picks its kernels by the CPU it runs on
(OpenBLAS's ``architecture``: SkylakeX, Haswell, ...) and numpy dispatches its loops by
the CPU's SIMD extensions, and their rounding differs in the last bits, which an
iterative fit (k-means, IRLS, Newton) and a threshold can carry into a millimetre.  The
results carry the CPU's model and the BLAS builds with their kernels too, so two runs'
numbers are compared knowing whether they ran alike.
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
    return {"commit": commit, "python": platform.python_version(), **versions, "cpu": _cpu_model(), "blas": _blas()}


def _cpu_model() -> str:
    """The CPU's model name (Linux's /proc/cpuinfo), else what the platform says."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _blas() -> str:
    """The BLAS libraries loaded (numpy's and scipy's), each with its version and the
    kernels it chose for this CPU, as threadpoolctl reports them."""
    import numpy  # noqa: F401  (load the libraries whose BLAS is reported)
    import scipy.linalg  # noqa: F401
    from threadpoolctl import threadpool_info

    return "; ".join(sorted({f"{info.get('internal_api')} {info.get('version')} {info.get('architecture') or ''}".strip()
                             for info in threadpool_info() if info.get("user_api") == "blas"}))


def environment_line(env: dict | None) -> str:
    """The environment in one line of a results page (or that the run did not record it)."""
    if not env:
        return "Environment: not recorded (a run before benchmarks/provenance.py)."
    libraries = ", ".join(f"{name} {env.get(name, '?')}" for name in NUMERICAL)
    machine = f"; CPU {env['cpu']}, BLAS {env.get('blas') or '?'}" if env.get("cpu") else ""
    return f"Environment: commit {env.get('commit') or '?'}, Python {env.get('python', '?')}, {libraries}{machine}."
