"""Command line: calf-nurbs fit | export | serve | worker | design | keys.

Exit codes: 0 success, 2 bad usage, 3 the scan, record or a file cannot be processed
(the reason is printed to stderr as JSON {"error": reason, "detail": ...}); 141, quietly,
when the reader of stdout stops reading (`| head`).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from app.cad import CAD_FORMATS
from app.geometry.errors import FitFailure

#: the exit status of a command whose stdout's reader stopped reading (128 + SIGPIPE, as a
#: shell reports a tool the signal ended)
SIGPIPE_EXIT = 141


def _fail(exc: FitFailure) -> int:
    print(json.dumps({"error": exc.reason.value, "detail": exc.detail}), file=sys.stderr)
    return 3


def _file_failure(exc: OSError) -> int:
    """A file the command was told to read or write cannot be (exit 3, JSON)."""
    what = exc.strerror or type(exc).__name__
    where = f": {exc.filename}" if exc.filename else ""
    print(json.dumps({"error": "file_error", "detail": f"{what}{where}"}), file=sys.stderr)
    return 3


EPILOG = """examples:
  calf-nurbs fit leg.stl -o leg.json                    # paper mode, 7 x 15 feature points
  calf-nurbs fit body.glb --side left --units cm -o leg.json
  calf-nurbs fit leg.ply --mode lsq --grid 12x24 -o leg.json
  calf-nurbs export leg.json --format step -o leg.step  # the exact B-spline (calf frame, mm)
  calf-nurbs export leg.json --format glb -o leg.glb    # a mesh in the scan's coordinates
  calf-nurbs design leg.json --standard RAL --class II --stiffness 10
  calf-nurbs size leg.json --chart example             # ready-to-wear size, or made to measure
  calf-nurbs keys create --tenant clinic-a
  calf-nurbs serve --port 8000

scan formats: {formats} (meshes or point clouds; units mm, cm, m or in,
  detected from the size when not given)
export formats: stl, glb, gltf (meshes); {cad} (exact B-spline)
compression classes: {classes}

exit codes: 0 done; 2 bad usage; 3 the scan, record or a file cannot be processed
  (stderr: JSON {{"error": reason, "detail": sentence}}); 141 quietly when the reader
  of stdout stops reading (| head)
"""


def _epilog() -> str:
    from app.geometry.garment.standards import COMPRESSION_CLASSES
    from app.geometry.scan.reader import SUPPORTED_FORMATS

    classes = "; ".join(f"{standard} {', '.join(spec['classes'])}" for standard, spec in COMPRESSION_CLASSES.items())
    return EPILOG.format(formats=", ".join(SUPPORTED_FORMATS), cad=", ".join(CAD_FORMATS), classes=classes)


def fit_summary(record_dict: dict) -> dict:
    """The short JSON a user sees after a fit."""
    fit = record_dict["fit"]
    return {
        "side": record_dict["side"],
        "landmarks": record_dict["landmarks"],
        "error_index": fit["error_index"],
        "error_index_exact": fit["error_index_exact"],
        "error_index_diameter": fit["error_index_diameter"],
        "max_error_mm": fit["max_error_mm"],
        "points_per_layer": fit["points_per_layer"],
        "mode": fit.get("mode", "paper"),
        **({"grid": fit["grid"]} if "grid" in fit else {}),
        # the order form's points off the calf (cB-cD are the landmarks' tape girths)
        "chart": {name: point["value_mm"] if point.get("value_mm") is not None else f"not measured: {point.get('reason')}"
                  for name, point in (record_dict.get("chart") or {}).items() if name != "thigh_profile"},
        "seconds": fit["seconds"],
    }


def _cmd_fit(args: argparse.Namespace) -> int:
    from app.geometry.fit.pipeline import FitOptions, fit_scan
    from app.geometry.scan.reader import load_scan
    from app.records.codec import record_from_fit

    started = time.perf_counter()
    try:
        scan = load_scan(args.scan, units=args.units)
        options = FitOptions(
            side=args.side,
            points_per_layer=args.points,
            n_sections=args.sections,
            section_spacing_mm=args.spacing,
            mode=args.mode,
            grid=args.grid,
        )
        result = fit_scan(scan, options)
    except FitFailure as exc:
        return _fail(exc)
    record = record_from_fit(result, scan.source_format, scan.units, time.perf_counter() - started).to_dict()
    if args.output:
        Path(args.output).write_text(json.dumps(record))
    print(json.dumps(fit_summary(record), indent=2))
    return 0


def _load_record(path: str):
    from app.records.codec import CalfRecord

    data = Path(path).read_bytes()  # a file that cannot be read: main's file_error
    try:
        return CalfRecord.from_dict(json.loads(data.decode("utf-8")))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        from app.geometry.errors import FailureReason

        where = f" (line {exc.lineno})" if isinstance(exc, json.JSONDecodeError) else ""
        raise FitFailure(FailureReason.INVALID_RECORD, f"{path} is not a record's JSON{where}") from exc


def _cmd_export(args: argparse.Namespace) -> int:
    from app.records.meshes import export_mesh, surface_mesh

    try:
        record = _load_record(args.record)
    except FitFailure as exc:
        return _fail(exc)
    try:
        surface = record.surface_of(args.part)  # the calf, or the leg model from B to G
    except FitFailure as exc:
        return _fail(exc)
    if args.format in CAD_FORMATS:
        from app.cad import export_surface

        data = export_surface(surface, args.format)
        Path(args.output).write_bytes(data)
        nu, nv = surface.shape
        print(json.dumps({"written": args.output, "format": args.format, "part": args.part, "exact": True,
                          "control_points": [nu, nv], "frame": "calf (B at the origin, z up the leg, y anterior), mm"}))
        return 0
    mesh = surface_mesh(surface, record.frame, n_u=args.around, n_v=args.along)
    Path(args.output).write_bytes(export_mesh(mesh, args.format))
    print(json.dumps({"written": args.output, "format": args.format, "faces": int(len(mesh.faces))}))
    return 0


def _cmd_serve(args: argparse.Namespace) -> int:
    import os

    import uvicorn

    from app.db.migrate import upgrade_to_head
    from app.logs import configure_logging
    from app.settings import get_settings

    # the bound address decides whether auth is required by default (CALF_AUTH)
    os.environ["CALF_HOST"] = args.host
    get_settings.cache_clear()
    settings = get_settings()
    configure_logging(settings.log_level, json=settings.log_json)
    upgrade_to_head(settings.resolved_database_url)
    # uvicorn's own logging config would replace ours (log_config=None keeps it); the
    # request line is the service's (access_log off)
    uvicorn.run("app.main:app", host=args.host, port=args.port, workers=1, log_config=None, access_log=False)
    return 0


def _keys_session():
    from app.db.migrate import upgrade_to_head
    from app.db.session import session_factory
    from app.settings import get_settings

    url = get_settings().resolved_database_url
    upgrade_to_head(url)
    return session_factory(url)()


def _cmd_keys(args: argparse.Namespace) -> int:
    """Admin: API keys of the tenants (clinics), on the service's database."""
    from app.errors import ServiceError
    from app.services.keys import KeyService, parse_scopes

    with _keys_session() as session:
        service = KeyService(session)
        try:
            if args.keys_command == "create":
                issued = service.create(args.tenant, parse_scopes(args.scopes), args.label, args.expires_days)
                expires = issued.expires_at.isoformat(timespec="seconds") if issued.expires_at else "never"
                print(f"tenant: {issued.tenant}\nprefix: {issued.prefix}\nscopes: {' '.join(issued.scopes)}\n"
                      f"expires: {expires}\nthe key is shown only now; give it to the clinic:")
                print(issued.key)
            elif args.keys_command == "list":
                print("prefix\ttenant\tscopes\tcreated\texpires\trevoked\tlast_used\tlabel")
                for key, tenant in service.listing(args.tenant):
                    when = [t.isoformat(timespec="seconds") if t else "-" for t in
                            (key.created_at, key.expires_at, key.revoked_at, key.last_used_at)]
                    print("\t".join([key.prefix, tenant, key.scopes.replace(" ", ","), *when, key.label or "-"]))
            else:
                key = service.revoke(args.prefix)
                print(f"revoked {key.prefix}")
        except ServiceError as exc:
            if exc.status == 404:  # a well-formed prefix of no key: not processed (3), as a missing file
                print(json.dumps({"error": exc.code, "detail": exc.detail}), file=sys.stderr)
                return 3
            print(f"error: {exc.detail}", file=sys.stderr)  # a malformed argument (scopes): bad usage
            return 2
    return 0


def _cmd_worker(args: argparse.Namespace) -> int:
    """Run fitting jobs from the database without serving HTTP (an API process started
    with CALF_RUN_JOBS=false hands its jobs to processes like this one)."""
    import asyncio
    import signal

    from app.db.migrate import upgrade_to_head
    from app.db.session import session_factory
    from app.jobs.runner import EmbeddedRunner
    from app.logs import configure_logging
    from app.services.storage import ScanStore
    from app.settings import get_settings

    settings = get_settings()
    configure_logging(settings.log_level, json=settings.log_json)
    upgrade_to_head(settings.resolved_database_url)
    if settings.broker_url:
        # scale-out: Dramatiq worker processes (one fit each) on the broker's queue
        from dramatiq.cli import main as dramatiq_main
        from dramatiq.cli import make_argument_parser

        from app.jobs.dramatiq_queue import QUEUE

        return dramatiq_main(make_argument_parser().parse_args(
            ["app.jobs.dramatiq_queue", "--processes", str(settings.workers), "--threads", "1", "--queues", QUEUE]))

    async def run() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, stop.set)
        runner = EmbeddedRunner(
            session_factory(settings.resolved_database_url),
            ScanStore(settings.scan_dir, settings.tmp_dir, settings.placed_dir),
            settings.workers,
            settings.job_timeout_s,
            lease_s=settings.job_lease_s,
            max_attempts=settings.job_max_attempts,
            worker_memory_bytes=settings.worker_memory_bytes,
            fits_per_tenant=settings.fits_per_tenant,
        )
        await runner.start()
        print(json.dumps({"worker": "started", "processes": settings.workers}), flush=True)
        try:
            await stop.wait()
        finally:
            await runner.stop()

    asyncio.run(run())
    return 0


def _cmd_design(args: argparse.Namespace) -> int:
    from app.services.design_cli import run_design_cli

    try:
        record = _load_record(args.record)
        return run_design_cli(record, args)
    except FitFailure as exc:
        return _fail(exc)


def _cmd_size(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from app.geometry.garment.size_charts import record_chart_measures, size_chart_dict_from_csv, size_chart_from_dict, size_decision
    from app.services.size_charts import EXAMPLE_AG_CHART_ID, EXAMPLE_CHART_ID, example_chart

    examples = {"example": EXAMPLE_CHART_ID, "example-ag": EXAMPLE_AG_CHART_ID}
    try:
        record = _load_record(args.record)
        if args.chart in examples:
            chart = example_chart(examples[args.chart])
        else:
            text = Path(args.chart).read_text()
            chart = size_chart_from_dict(size_chart_dict_from_csv(text) if args.chart.lower().endswith(".csv") else json.loads(text))
    except FitFailure as exc:
        return _fail(exc)
    except OSError as exc:
        return _file_failure(exc)
    except json.JSONDecodeError as exc:
        from app.geometry.errors import FailureReason

        return _fail(FitFailure(FailureReason.INVALID_SIZE_CHART, f"the chart is not JSON: {exc.msg} (line {exc.lineno})"))
    decision = size_decision(chart, record_chart_measures(record.landmarks, record.scan.get("sole_mm"), record.chart))
    if args.json:
        print(json.dumps({"chart": chart.product, **asdict(decision)}, indent=2))
    else:
        print(f"{chart.product} ({chart.stocking_type}): {decision.decision}")
        if decision.best:
            print(f"  fits: {', '.join(decision.fitting)}; best {decision.best}")
        for check in decision.outside:
            print(f"  {check.point} {check.measured_mm:.0f} mm is {abs(check.excess_mm):.0f} mm "
                  f"{'above' if check.excess_mm > 0 else 'below'} size {decision.nearest} ({check.low_mm:g}-{check.high_mm:g})")
        if decision.missing:
            print(f"  not in the record: {', '.join(decision.missing)}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    from app.geometry.garment.design import (
        DEFAULT_CLASS,
        DEFAULT_HOT_SPOT_MMHG,
        DEFAULT_STANDARD,
        DEFAULT_STIFFNESS_N_PER_CM,
        DEFAULT_STOCKING_TYPE,
        DEFAULT_TOE,
    )
    from app.geometry.garment.fabric import DEFAULT_MAX_STRAIN

    parser = argparse.ArgumentParser(prog="calf-nurbs", description="Fit an exact NURBS model to a 3D scan of a leg, "
                                     "measure it and design a graduated compression stocking from it.",
                                     epilog=_epilog(), formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)

    fit = sub.add_parser("fit", help="fit the NURBS calf model to a scan")
    fit.add_argument("scan")
    fit.add_argument("--side", choices=["left", "right"])
    fit.add_argument("--units", choices=["mm", "cm", "m", "in"])
    fit.add_argument("--points", type=int, default=15, help="feature points per layer (paper: 8 or 15)")
    fit.add_argument("--sections", type=int, default=200, help="resampled sections between B and D")
    fit.add_argument("--spacing", type=float, help="section spacing in mm (overrides --sections)")
    fit.add_argument("--mode", choices=["paper", "paper_stacked", "lsq"], default="paper",
                     help="paper: interpolate 7 x points feature points; lsq: least squares on all the calf's points")
    fit.add_argument("--grid", default="7x15", help="lsq control net ALONGxAROUND (default 7x15, e.g. 12x24)")
    fit.add_argument("-o", "--output", help="write the record JSON here")
    fit.set_defaults(func=_cmd_fit)

    export = sub.add_parser("export", help="write a record's surface: STL/GLB/glTF meshes in scan coordinates, or "
                            "the exact B-spline as STEP/IGES/3dm/geomdl JSON in the calf frame (mm)")
    export.add_argument("record")
    export.add_argument("--format", choices=["stl", "glb", "gltf", *CAD_FORMATS], default="stl")
    export.add_argument("--around", type=int, default=144, help="samples around the leg")
    export.add_argument("--along", type=int, default=100, help="samples along the leg")
    export.add_argument("--part", choices=["calf", "leg"], default="calf",
                        help="calf: the paper's calf, B to D (default); leg: the leg model from B to G, when the scan "
                             "reached the top of the thigh")
    export.add_argument("-o", "--output", required=True)
    export.set_defaults(func=_cmd_export)

    serve = sub.add_parser("serve", help="migrate the database, then serve the HTTP API")
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--port", type=int, default=8000)
    serve.set_defaults(func=_cmd_serve)

    worker = sub.add_parser("worker", help="run queued fitting jobs (no HTTP); for CALF_RUN_JOBS=false API processes")
    worker.set_defaults(func=_cmd_worker)

    keys = sub.add_parser("keys", help="API keys of the tenants (clinics): create, list, revoke")
    keys_sub = keys.add_subparsers(dest="keys_command", required=True)
    create = keys_sub.add_parser("create", help="a new key; printed alone on the last line, once")
    create.add_argument("--tenant", required=True, help="the clinic (created if new)")
    create.add_argument("--scopes", default="upload,read,design", help="some of upload,read,design,admin")
    create.add_argument("--label", help="a note: who or what the key is for")
    create.add_argument("--expires-days", type=float, help="the key expires after this many days")
    listing = keys_sub.add_parser("list", help="keys (prefixes, never secrets)")
    listing.add_argument("--tenant")
    revoke = keys_sub.add_parser("revoke", help="revoke a key by its prefix (cnk_xxxxxxxx)")
    revoke.add_argument("prefix")
    keys.set_defaults(func=_cmd_keys)

    design = sub.add_parser("design", help="design a graduated compression stocking from a record")
    design.add_argument("record")
    design.add_argument("--class", dest="compression_class", default=DEFAULT_CLASS)
    design.add_argument("--standard", default=DEFAULT_STANDARD, choices=["RAL", "BS", "AFNOR"])
    design.add_argument("--stiffness", type=float, default=DEFAULT_STIFFNESS_N_PER_CM,
                        help=f"fabric stiffness K, N/cm per unit strain ({DEFAULT_STIFFNESS_N_PER_CM:g})")
    design.add_argument("--max-strain", type=float, default=DEFAULT_MAX_STRAIN,
                        help="largest strain of a linear fabric (1.0 = 100%%)")
    design.add_argument("--table", help="CSV of the fabric's measured strain,tension_N_per_cm (instead of --stiffness)")
    design.add_argument("--hot-spot-limit", type=float, default=DEFAULT_HOT_SPOT_MMHG,
                        help=f"local pressure hot-spot limit, mmHg ({DEFAULT_HOT_SPOT_MMHG:g})")
    design.add_argument("--type", default=DEFAULT_STOCKING_TYPE, choices=["AD", "AG"],
                        help="AD knee-high (default) or AG thigh-high (needs a record whose scan reaches the gluteal fold)")
    design.add_argument("--toe", default=DEFAULT_TOE, choices=["closed", "open"], help="the stocking's toe (closed)")
    design.add_argument("--top-band", type=float, default=None, metavar="MM",
                        help="the top band's width, mm (25 for AD, 50 for AG; 0: none)")
    design.add_argument("--json", action="store_true", help="print the whole design as JSON")
    design.set_defaults(func=_cmd_design)

    size = sub.add_parser("size", help="the ready-to-wear size decision of a record on a size chart")
    size.add_argument("record")
    size.add_argument("--chart", default="example",
                      help="a chart file (.json, or .csv with size,point,min_mm,max_mm), or 'example' (knee-high) or "
                           "'example-ag' (thigh-high), both ANSUR II-derived")
    size.add_argument("--json", action="store_true", help="print the decision with every size's checks as JSON")
    size.set_defaults(func=_cmd_size)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        status = args.func(args)
        sys.stdout.flush()  # a closed reader fails here, not in the interpreter's last flush
        return status
    except FitFailure as exc:
        return _fail(exc)
    except BrokenPipeError:
        # the reader of stdout stopped reading (`| head`, a pager closed): not a file of
        # the command's; end quietly as a Unix tool killed by SIGPIPE does, stdout sent
        # to /dev/null so that the interpreter's last flush does not fail again
        # (the Python documentation's note on SIGPIPE, signal module)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return SIGPIPE_EXIT
    except OSError as exc:  # a file named on the command line: missing, a folder, not writable
        return _file_failure(exc)
    except UnicodeDecodeError:  # a record, chart or fabric table that is not text
        print(json.dumps({"error": "file_error", "detail": "a file named on the command line is not UTF-8 text: records "
                          "and charts are JSON or CSV, fabric tables CSV"}), file=sys.stderr)
        return 3


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
