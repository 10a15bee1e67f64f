"""The fitting service layer: a stored scan file and options in, a calf record out.

The functions below run inside worker processes (they only take and return plain,
picklable values), so CPU-bound fitting never blocks the web server's event loop.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import gc
import os
import time

from app.geometry.errors import FailureReason, FitFailure
from app.geometry.fit.pipeline import FitOptions, fit_placed_leg, fit_scan, place_scan
from app.geometry.placement import LegPlacement
from app.geometry.scan.reader import UNIT_SCALE_MM, load_scan
from app.geometry.spline.lsq import LsqGrid
from app.records.codec import record_from_fit
from app.services.placed_legs import take_placed_leg, write_placed_leg

#: the C library (malloc_trim here, prctl in app.jobs.runner), None where there is none
_LIBC_NAME = ctypes.util.find_library("c")
LIBC = ctypes.CDLL(_LIBC_NAME, use_errno=True) if _LIBC_NAME else None
DEFAULT_POINTS = 15
DEFAULT_GRID = "7x15"
#: surface modes an upload may ask for ("paper_stacked" is a study of the paper's text,
#: kept for the CLI and the benchmarks)
UPLOAD_MODES = ("paper", "lsq")


def parse_options(side: str | None, units: str | None, points: str | int | None,
                  mode: str | None = None, grid: str | None = None) -> dict:
    """Validate upload options (form fields or query parameters) into the job's options:
    side, units, points, mode ("paper" or "lsq") and, for lsq, grid ("ALONGxAROUND")."""

    def invalid(detail: str) -> FitFailure:
        return FitFailure(FailureReason.INVALID_OPTION, detail)

    side = (side or "").strip().lower() or None
    if side not in (None, "left", "right"):
        raise invalid(f"side must be 'left' or 'right', not {side!r}")
    units = (units or "").strip().lower() or None
    if units not in (None, *UNIT_SCALE_MM):
        raise invalid(f"units must be one of mm, cm, m, in, not {units!r}")
    if points in (None, ""):
        m = DEFAULT_POINTS
    else:
        try:
            m = int(points)
        except (TypeError, ValueError) as exc:
            raise invalid(f"points must be an integer (8 or 15 in the paper), not {points!r}") from exc
    mode = (mode or "").strip().lower() or "paper"
    if mode not in UPLOAD_MODES:
        raise invalid(f"mode must be one of {', '.join(UPLOAD_MODES)}, not {mode!r}")
    options = {"side": side, "units": units, "points": m, "mode": mode}
    if mode == "lsq":
        options["grid"] = str(LsqGrid.parse(grid or DEFAULT_GRID))
    elif grid not in (None, ""):
        raise invalid("grid applies to mode=lsq only")
    fit_options(options).validate()
    return options


def fit_options(options: dict) -> FitOptions:
    """The fit options of a job's stored options (jobs stored before modes are paper)."""
    return FitOptions(side=options.get("side"), points_per_layer=int(options.get("points", DEFAULT_POINTS)),
                      mode=options.get("mode", "paper"), grid=options.get("grid", DEFAULT_GRID))


@contextlib.contextmanager
def worker_task():
    """Around a worker's task: a MemoryError (the worker's RLIMIT_AS,
    app.jobs.runner.prepare_worker) becomes ``scan_too_large``, and the memory the
    task freed is handed back to the system (glibc keeps freed arenas otherwise: an idle
    worker held 1.2 GB after a large scan)."""
    try:
        yield
    except MemoryError:
        raise FitFailure(FailureReason.SCAN_TOO_LARGE, "the scan needs more memory than this service gives one scan "
                         "(CALF_WORKER_MEMORY_MB): decimate the mesh or subsample the cloud (1-2 mm spacing is "
                         "plenty) and upload it again") from None
    finally:
        gc.collect()
        if LIBC is not None and hasattr(LIBC, "malloc_trim"):  # glibc
            LIBC.malloc_trim(0)


def warm_up() -> None:
    """Worker: nothing - this module and its imports (numpy, scipy, trimesh) are loaded
    when the call arrives; the pools call it once per worker at start."""


def set_priority(nice: int) -> None:
    """Worker: run this task at CPU priority ``nice`` (0 normal; app.jobs.runner gives a
    clinic's second concurrent task SECOND_TASK_NICE, so that on a busy machine another
    clinic's task gets the CPU first).  Lowering it again needs root or CAP_SYS_NICE;
    without them the worker keeps the higher value for its later tasks (never worse
    than one clinic's tasks all at one priority)."""
    try:
        if os.getpriority(os.PRIO_PROCESS, 0) != nice:
            os.setpriority(os.PRIO_PROCESS, 0, nice)
    except OSError:
        pass


def validate_scan_file(path: str, file_format: str, options: dict, max_points: int | None = None,
                       max_faces: int | None = None, nice: int = 0, placed_leg: str | None = None) -> dict:
    """Worker: read the scan and place its calf; raises FitFailure with the reason
    (scan_too_large beyond ``max_points`` / ``max_faces``).  Returns the placement as the
    JSON the job stores (the one place it is serialised; :func:`fit_scan_file` reads it)
    and, given ``placed_leg``, writes there the leg it cut out for the job's fit
    (:mod:`app.services.placed_legs`)."""
    set_priority(nice)
    with worker_task():
        scan = load_scan(path, file_type=file_format, units=options.get("units"), max_points=max_points,
                         max_faces=max_faces)
        leg = place_scan(scan, fit_options(options))
        if placed_leg is not None:
            write_placed_leg(placed_leg, leg, scan)
        return leg.placement.to_dict()


def fit_scan_file(path: str, file_format: str, options: dict, placement: dict | None = None, nice: int = 0,
                  placed_leg: str | None = None) -> dict:
    """Worker: the whole fit; returns {"record": record JSON, "stage_seconds": {...}}.

    ``placement``: what the upload check found (see app.geometry.fit.pipeline.check_scan); the
    fit then skips locating the calf again.  ``placed_leg``: the file where the check
    left the leg it cut out (:mod:`app.services.placed_legs`); when it is there, the fit
    starts from it (and removes it) instead of reading and cleaning the scan again.
    """
    set_priority(nice)
    started = time.perf_counter()
    with worker_task():
        handed = take_placed_leg(placed_leg, placement) if placed_leg and placement else None
        if handed is not None:
            loaded = time.perf_counter()
            result = fit_placed_leg(handed.leg, handed.n_scan_points, fit_options(options))
            source_format, units = handed.source_format, handed.units
        else:
            scan = load_scan(path, file_type=file_format, units=options.get("units"))
            loaded = time.perf_counter()
            result = fit_scan(scan, fit_options(options), LegPlacement.from_dict(placement) if placement else None)
            source_format, units = scan.source_format, scan.units
        seconds = time.perf_counter() - started
        record = record_from_fit(result, source_format, units, seconds).to_dict()
    stages = {"load": loaded - started, **{k: float(v) for k, v in result.timings.items()}, "total": seconds}
    return {"record": record, "stage_seconds": stages}
