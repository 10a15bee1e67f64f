"""Service benchmark: upload-to-record latency and throughput with 2 worker processes,
against the fit time of the core itself on the same scans, and GET latency while fits run.

Run:  .venv/bin/python benchmarks/bench_service.py
It starts `calf-nurbs serve` on 127.0.0.1 (a free port, a temporary data directory,
embedded SQLite), drives it over real HTTP with httpx, stops it, and writes
benchmarks/results/service.md (+ service.json).  All traffic stays on loopback and every
loop is bounded.
"""

from __future__ import annotations

import os

# one BLAS thread, as benchmarks/bench_fit.py: the core's reference fit and the served
# workers (which inherit this environment) alike, whatever the caller's shell sets
for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import json  # noqa: E402
import platform  # noqa: E402
import socket  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import httpx  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from app.geometry.fit.pipeline import FitOptions, fit_scan  # noqa: E402
from app.geometry.scan.reader import load_scan  # noqa: E402
from benchmarks.ratios import paired_ratio  # noqa: E402

DATA = ROOT / "tests" / "data" / "real"
RESULTS = ROOT / "benchmarks" / "results"
SCANS = [
    ("bodyparts3d_right_leg.stl", None, "model/stl"),
    ("vh_female_skin.glb", "left", "model/gltf-binary"),
    ("vh_male_skin.glb", "right", "model/gltf-binary"),
]
#: sequential uploads per scan, each right after the core's own load + fit of the same file
#: (a pair): with 3 rounds the ratio of the two medians ranged 0.94x-1.54x over five runs on
#: the same commit, the core's fit and the upload measured minutes apart on a machine whose
#: speed drifts; each pair's ratio is read on one moment's machine
LATENCY_ROUNDS = 9
THROUGHPUT_JOBS = 18  # submitted at once, from UPLOADERS concurrent clients
UPLOADERS = 3
POLL_S = 0.02  # job polling interval when measuring latency
THROUGHPUT_POLL_S = 0.1  # ... and of the concurrent uploaders
READER_PAUSE_S = 0.02  # the GET client's pause between requests


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def core_fit_once(file: str, side: str | None) -> float:
    """Seconds of one load + fit of ``file`` in this process: what `calf-nurbs fit` spends."""
    start = time.perf_counter()
    fit_scan(load_scan(DATA / file), FitOptions(side=side))
    return time.perf_counter() - start


def wait_job(client: httpx.Client, location: str, timeout: float = 120.0, poll: float | None = None) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        job = client.get(location).json()
        if job["status"] in ("succeeded", "failed"):
            return job
        time.sleep(POLL_S if poll is None else poll)
    raise TimeoutError(location)


def post_scan(client: httpx.Client, file: str, side: str | None, media: str) -> str:
    params = {"side": side} if side else {}
    response = client.post("/api/v1/scans", content=(DATA / file).read_bytes(), params=params, headers={"Content-Type": media})
    response.raise_for_status()
    return response.headers["location"]


def main() -> None:
    RESULTS.mkdir(parents=True, exist_ok=True)
    for file, side, _ in SCANS:  # warm-up
        core_fit_once(file, side)
    port = free_port()
    data_dir = Path(tempfile.mkdtemp(prefix="calf-bench-"))
    # the benchmark measures speed, not the fair-share limits: one clinic (no keys) sends
    # every upload and polls its jobs, so its request and upload rates and its queued-jobs cap
    # are lifted for the run
    env = {**os.environ, "CALF_DATA_DIR": str(data_dir), "CALF_WORKERS": "2", "CALF_RATE_LIMIT": "0", "CALF_UPLOAD_RATE_LIMIT": "0",
           "CALF_TENANT_MAX_JOBS": "1000"}
    server = subprocess.Popen(
        [str(Path(sys.executable).parent / "calf-nurbs"), "serve", "--host", "127.0.0.1", "--port", str(port)],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    base = f"http://127.0.0.1:{port}"
    try:
        with httpx.Client(base_url=base, timeout=120.0) as client:
            for _ in range(200):  # up to 20 s for start-up
                try:
                    if client.get("/readyz").status_code == 200:
                        break
                except httpx.TransportError:
                    pass
                time.sleep(0.1)
            # warm the worker processes (spawned lazily on first use)
            for file, side, media in SCANS:
                wait_job(client, post_scan(client, file, side, media))

            idle_get = []
            record_id = client.get("/api/v1/records", params={"limit": 1}).json()["items"][0]["id"]
            for _ in range(50):
                start = time.perf_counter()
                client.get(f"/api/v1/records/{record_id}").raise_for_status()
                idle_get.append(time.perf_counter() - start)

            latency: dict[str, list[float]] = {file: [] for file, _, _ in SCANS}
            core_times: dict[str, list[float]] = {file: [] for file, _, _ in SCANS}
            for _ in range(LATENCY_ROUNDS):
                for file, side, media in SCANS:
                    core_times[file].append(core_fit_once(file, side))
                    start = time.perf_counter()
                    job = wait_job(client, post_scan(client, file, side, media))
                    assert job["status"] == "succeeded", job
                    latency[file].append(time.perf_counter() - start)
            core = {file: statistics.median(times) for file, times in core_times.items()}

            from concurrent.futures import ThreadPoolExecutor

            def submit_and_wait(i: int, poll: float) -> dict:
                with httpx.Client(base_url=base, timeout=120.0) as uploader:
                    return wait_job(uploader, post_scan(uploader, *SCANS[i % len(SCANS)]), timeout=600, poll=poll)

            # throughput: many uploads at once from a few clients that poll like real ones
            start = time.perf_counter()
            with ThreadPoolExecutor(UPLOADERS) as uploaders:
                jobs = list(uploaders.map(lambda i: submit_and_wait(i, THROUGHPUT_POLL_S), range(THROUGHPUT_JOBS)))
            elapsed = time.perf_counter() - start
            assert all(j["status"] == "succeeded" for j in jobs)

            # GET latency while a second batch of fits runs
            busy_get: list[float] = []
            with ThreadPoolExecutor(UPLOADERS) as uploaders:
                batch = [uploaders.submit(submit_and_wait, i, THROUGHPUT_POLL_S) for i in range(THROUGHPUT_JOBS)]
                time.sleep(0.5)
                while not all(f.done() for f in batch) and len(busy_get) < 5000:
                    begin = time.perf_counter()
                    client.get(f"/api/v1/records/{record_id}").raise_for_status()
                    busy_get.append(time.perf_counter() - begin)
                    time.sleep(READER_PAUSE_S)
                assert all(f.result()["status"] == "succeeded" for f in batch)
    finally:
        server.terminate()
        server.wait(timeout=30)

    mean_core = float(np.mean([core[SCANS[i % len(SCANS)][0]] for i in range(THROUGHPUT_JOBS)]))
    ideal = 2.0 / mean_core  # two workers, no overhead
    results = {
        "core_fit_s": core,
        "upload_to_record_s": {f: statistics.median(v) for f, v in latency.items()},
        # each upload over the core's fit just before it: median and quartiles over the rounds
        "upload_over_core": {f: paired_ratio(latency[f], core_times[f]) for f in latency},
        "throughput_jobs_per_s": THROUGHPUT_JOBS / elapsed,
        "ideal_jobs_per_s": ideal,
        "get_idle_ms": {"median": 1e3 * statistics.median(idle_get), "p95": 1e3 * float(np.percentile(idle_get, 95))},
        "get_busy_ms": {"median": 1e3 * statistics.median(busy_get), "p95": 1e3 * float(np.percentile(busy_get, 95)), "n": len(busy_get)},
    }
    (RESULTS / "service.json").write_text(json.dumps(results, indent=1))
    lines = [
        "# Service benchmark",
        "",
        f"`calf-nurbs serve` with 2 worker processes and embedded SQLite, driven over loopback HTTP "
        f"(httpx); Python {platform.python_version()}, {os.cpu_count()} cores, one BLAS thread. Reproduce: "
        "`.venv/bin/python benchmarks/bench_service.py`. Medians; the reference is the core's own "
        "load + fit of the same file in the same run (what `calf-nurbs fit` spends).",
        "",
        "## Upload to record, one at a time",
        "",
        f"{LATENCY_ROUNDS} rounds; each upload right after the core's own load + fit of the same file, the "
        "overhead ratio the median of each pair's ratio (quartiles in brackets).",
        "",
        "| scan | core fit s | upload -> record s | overhead ratio |",
        "|---|---|---|---|",
    ]
    for file, _, _ in SCANS:
        service_s = results["upload_to_record_s"][file]
        ratio = results["upload_over_core"][file]
        lines.append(f"| {file} | {core[file]:.3f} | {service_s:.3f} | {ratio['median']:.2f}x ({ratio['p25']:.2f}-{ratio['p75']:.2f}) |")
    lines += [
        "",
        "The overhead is the upload itself, the acceptance check (the file is read and the calf",
        "located in a worker before anything is stored, so bad scans are refused with a 4xx),",
        "the job hand-off to a worker process (the fit starts from the leg the check cut out and",
        "placed, app.services.placed_legs: the scan is read, cleaned and placed once per upload),",
        "storing the record, and the client's polling interval (20 ms).",
        "",
        "## Throughput, 2 workers",
        "",
        f"{THROUGHPUT_JOBS} uploads from {UPLOADERS} concurrent clients (each uploads, then polls its job "
        f"every {THROUGHPUT_POLL_S * 1e3:.0f} ms): {results['throughput_jobs_per_s']:.2f} jobs/s; two workers with no "
        f"overhead at all would do {ideal:.2f} jobs/s (ratio {results['throughput_jobs_per_s'] / ideal:.2f}). "
        "The machine has 2 cores, shared by the 2 workers, the server process and the clients, so the ideal "
        "is out of reach by construction; the ratio shows what the service costs on top of the fits.",
        "",
        "## GET latency while fits run",
        "",
        "| | median ms | p95 ms |",
        "|---|---|---|",
        f"| GET /api/v1/records/{{id}}, idle | {results['get_idle_ms']['median']:.1f} | {results['get_idle_ms']['p95']:.1f} |",
        f"| the same while {THROUGHPUT_JOBS} more uploads are fitted ({results['get_busy_ms']['n']} requests) | "
        f"{results['get_busy_ms']['median']:.1f} | {results['get_busy_ms']['p95']:.1f} |",
        "",
        f"Busy/idle median ratio: {results['get_busy_ms']['median'] / results['get_idle_ms']['median']:.2f}x. "
        "The fits run in other processes, so the event loop keeps answering; on a 2-core machine the "
        "remaining slowdown is CPU contention with the two workers.",
    ]
    (RESULTS / "service.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
