"""Shared fixtures: the vendored real meshes and cached fits of them."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

DATA = Path(__file__).parent / "data"
REAL = DATA / "real"

#: (file, side) of every real leg the tests use; +X is the subject's left in all files
REAL_LEGS = [
    ("bodyparts3d_right_leg.stl", None),
    ("vh_female_skin.glb", "left"),
    ("vh_female_skin.glb", "right"),
    ("vh_male_skin.glb", "left"),
    ("vh_male_skin.glb", "right"),
]

#: the scan axis pointing to the subject's front, per file (data README)
FRONT_AXIS = {"bodyparts3d_right_leg.stl": (0.0, -1.0, 0.0), "vh_female_skin.glb": (0.0, 0.0, 1.0), "vh_male_skin.glb": (0.0, 0.0, 1.0)}
UP_AXIS = {"bodyparts3d_right_leg.stl": (0.0, 0.0, 1.0), "vh_female_skin.glb": (0.0, 1.0, 0.0), "vh_male_skin.glb": (0.0, 1.0, 0.0)}


@pytest.fixture(scope="session")
def real_dir() -> Path:
    return REAL


_FITS: dict = {}


def fitted(file: str, side: str | None, points: int = 15):
    """Fit a vendored leg once per session (the fits are deterministic)."""
    from app.geometry.fit.pipeline import FitOptions, fit_scan
    from app.geometry.scan.reader import load_scan

    key = (file, side, points)
    if key not in _FITS:
        scan = load_scan(REAL / file)
        _FITS[key] = (scan, fit_scan(scan, FitOptions(side=side, points_per_layer=points)))
    return _FITS[key]


# --- the suite leaves no process behind ------------------------------------------------

#: how long the session's end waits for its child processes to finish exiting, s
CHILD_EXIT_GRACE_S = 15.0


def _descendants(pid: int) -> list[tuple[int, str]]:
    """(pid, command line) of every living descendant of ``pid``, from /proc (Linux);
    zombies (exited, not yet reaped) are not living."""
    proc = Path("/proc")
    parents: dict[int, list[int]] = {}
    for entry in proc.iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        if fields[0] == "Z":
            continue
        parents.setdefault(int(fields[1]), []).append(int(entry.name))
    found, todo = [], list(parents.get(pid, []))
    while todo:
        child = todo.pop()
        try:
            command = (proc / str(child) / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
        except OSError:
            continue
        found.append((child, command))
        todo.extend(parents.get(child, []))
    return found


def _left_behind() -> list[tuple[int, str]]:
    """Children still running, except multiprocessing's resource tracker (it exits with
    this process by design: it reads a pipe that closes when the interpreter ends)."""
    return [(pid, cmd) for pid, cmd in _descendants(os.getpid()) if "resource_tracker" not in cmd]


def pytest_sessionfinish(session, exitstatus):
    """Fail the run if a test left a process running (a server, a worker pool): the
    suite must leave the machine as it found it."""
    if not Path("/proc/self/stat").exists():
        return
    import time

    deadline = time.monotonic() + CHILD_EXIT_GRACE_S
    left = _left_behind()
    while left and time.monotonic() < deadline:
        time.sleep(0.5)
        left = _left_behind()
    if left:
        reporter = session.config.pluginmanager.get_plugin("terminalreporter")
        lines = "\n".join(f"  pid {pid}: {cmd[:200]}" for pid, cmd in left)
        message = f"the suite left {len(left)} process(es) running:\n{lines}"
        if reporter is not None:
            reporter.write_line(message, red=True)
        else:
            print(message)
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
