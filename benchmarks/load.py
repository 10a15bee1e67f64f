"""Load benchmark on localhost: N uploads from C concurrent clients against 2 fitting
workers, for the embedded runner (SQLite) and for Dramatiq on Redis + PostgreSQL.

Run:  .venv/bin/python benchmarks/load.py [UPLOADS] [CLIENTS]   (default 200, 20)
Writes benchmarks/results/load.md and load.json.

Bounded: only 127.0.0.1, a fixed number of requests, every wait with a deadline; the
servers it starts are stopped at the end.  Each mode: the uploads (the real BodyParts3D
leg, points 8..15 in turn), then every job followed to its end, then one GET of every
record.  Checked: every accepted upload ended as exactly one record (no job failed, no
record twice).  Reported: throughput and p50 / p99 of upload and record-GET latencies,
and fits per second from the first upload to the last record.  The Dramatiq mode is
skipped, saying why, without a Redis or PostgreSQL server.
"""

from __future__ import annotations

import asyncio
import json
import os
import sys
import tempfile
import time
import uuid
from pathlib import Path

import httpx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from benchmarks.served import free_port, start, stop, wait_ready  # noqa: E402

LEG = (ROOT / "tests" / "data" / "real" / "bodyparts3d_right_leg.stl").read_bytes()
RESULTS = ROOT / "benchmarks" / "results"
PG_ADMIN = os.environ.get("CALF_TEST_PG_ADMIN", "postgresql+psycopg://postgres@127.0.0.1:5432/postgres")
REDIS_URL = os.environ.get("CALF_TEST_REDIS", "redis://127.0.0.1:6379/0")


def percentile(values, q) -> float:
    return float(np.percentile(np.asarray(values), q)) if values else float("nan")


async def drive(base: str, uploads: int, clients: int) -> dict:
    upload_s, get_s, locations = [], [], []
    counter = iter(range(uploads))
    started = time.perf_counter()
    async with httpx.AsyncClient(timeout=300) as client:

        async def uploader():
            for i in counter:
                t = time.perf_counter()
                r = await client.post(f"{base}/api/v1/scans", content=LEG, params={"points": 8 + i % 8},
                                      headers={"Content-Type": "model/stl"})
                upload_s.append(time.perf_counter() - t)
                if r.status_code != 202:
                    raise RuntimeError(f"upload {i}: {r.status_code} {r.text[:200]}")
                locations.append(r.headers["location"])

        await asyncio.gather(*(uploader() for _ in range(clients)))
        accepted = time.perf_counter()
        jobs = {}
        deadline = time.monotonic() + 1800
        pending = list(locations)
        while pending and time.monotonic() < deadline:
            still = []
            for location in pending:
                job = (await client.get(base + location)).json()
                if job["status"] in ("succeeded", "failed"):
                    jobs[location] = job
                else:
                    still.append(location)
            pending = still
            if pending:
                await asyncio.sleep(0.5)
        finished = time.perf_counter()
        record_ids = [j["record_id"] for j in jobs.values() if j["status"] == "succeeded"]
        ids = iter(record_ids)

        async def reader():
            for record_id in ids:
                t = time.perf_counter()
                r = await client.get(f"{base}/api/v1/records/{record_id}")
                get_s.append(time.perf_counter() - t)
                assert r.status_code == 200

        await asyncio.gather(*(reader() for _ in range(clients)))
        listed, cursor = [], None
        while True:
            page = (await client.get(f"{base}/api/v1/records", params={"limit": 100, **({"cursor": cursor} if cursor else {})})).json()
            listed += [item["id"] for item in page["items"]]
            cursor = page.get("next_cursor")
            if not cursor:
                break
    failed = [j for j in jobs.values() if j["status"] != "succeeded"]
    return {
        "uploads": uploads, "clients": clients, "accepted": len(locations), "unfinished": len(pending),
        "failed_jobs": len(failed), "records": len(set(listed)), "records_listed": len(listed),
        "duplicate_records": len(record_ids) - len(set(record_ids)),
        "upload_p50_s": percentile(upload_s, 50), "upload_p99_s": percentile(upload_s, 99),
        "uploads_per_s": len(locations) / (accepted - started),
        "fits_per_s": len(record_ids) / (finished - started), "wall_s": finished - started,
        "get_p50_s": percentile(get_s, 50), "get_p99_s": percentile(get_s, 99),
    }


def run_mode(name: str, env: dict, worker_env: dict | None, uploads: int, clients: int) -> dict:
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    processes = [start(["serve", "--port", str(port)], env)]
    try:
        wait_ready(base, processes[0])
        if worker_env is not None:
            processes.append(start(["worker"], worker_env))
        result = asyncio.run(drive(base, uploads, clients))
    finally:
        stop(*processes)
    result["mode"] = name
    print(json.dumps(result), flush=True)
    return result


def dramatiq_env(data_dir: str) -> tuple[dict | None, str, object]:
    import redis
    from sqlalchemy import create_engine, text

    try:
        redis.Redis.from_url(REDIS_URL, socket_connect_timeout=2).ping()
        admin = create_engine(PG_ADMIN, isolation_level="AUTOCOMMIT")
        name = f"calf_load_{uuid.uuid4().hex[:8]}"
        with admin.connect() as conn:
            conn.execute(text(f'CREATE DATABASE "{name}"'))
    except Exception as exc:  # noqa: BLE001 - reported as the reason to skip
        return None, f"skipped: no Redis or PostgreSQL server ({type(exc).__name__})", None
    env = {"CALF_DATA_DIR": data_dir, "CALF_DATABASE_URL": PG_ADMIN.rsplit("/", 1)[0] + "/" + name,
           "CALF_BROKER_URL": REDIS_URL, "CALF_BROKER_NAMESPACE": f"calf-load-{name}", "CALF_UPLOAD_RATE_LIMIT": "0",
           "CALF_RATE_LIMIT": "0", "CALF_LOG_LEVEL": "WARNING"}

    def drop():
        with admin.connect() as conn:
            conn.execute(text(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)'))
        client = redis.Redis.from_url(REDIS_URL)
        for key in client.scan_iter(f"calf-load-{name}*"):
            client.delete(key)

    return env, "", drop


def main() -> None:
    uploads = int(sys.argv[1]) if len(sys.argv) > 1 else 200
    clients = int(sys.argv[2]) if len(sys.argv) > 2 else 20
    results, notes = [], []
    with tempfile.TemporaryDirectory() as tmp:
        embedded = {"CALF_DATA_DIR": f"{tmp}/embedded", "CALF_WORKERS": "2", "CALF_UPLOAD_RATE_LIMIT": "0",
                    "CALF_RATE_LIMIT": "0", "CALF_LOG_LEVEL": "WARNING"}
        results.append(run_mode("embedded (SQLite, 2 pool workers)", embedded, None, uploads, clients))
        env, why, drop = dramatiq_env(f"{tmp}/dramatiq")
        if env is None:
            notes.append(f"Dramatiq + PostgreSQL: {why}")
        else:
            try:
                results.append(run_mode("Dramatiq + PostgreSQL (2 worker processes)", {**env, "CALF_WORKERS": "1"},
                                        {**env, "CALF_WORKERS": "2"}, uploads, clients))
            finally:
                drop()
    (RESULTS / "load.json").write_text(json.dumps({"results": results, "notes": notes}, indent=1))
    lines = [f"# Load: {uploads} uploads from {clients} concurrent clients, 2 fitting workers, localhost", "",
             f"`.venv/bin/python benchmarks/load.py {uploads} {clients}`; the real BodyParts3D leg (1.3 MB STL); "
             "one machine of 2 cores runs the clients, the API, the workers and the servers.", "",
             "| mode | accepted | records | failed | duplicates | uploads/s | upload p50 / p99 s | fits/s | record GET p50 / p99 ms |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| {r['mode']} | {r['accepted']} | {r['records']} | {r['failed_jobs']} | {r['duplicate_records']} | "
                     f"{r['uploads_per_s']:.2f} | {r['upload_p50_s']:.2f} / {r['upload_p99_s']:.2f} | {r['fits_per_s']:.2f} | "
                     f"{1000 * r['get_p50_s']:.1f} / {1000 * r['get_p99_s']:.1f} |")
    lines += ["", *notes, "", "An upload's latency includes its acceptance check (the file read and the calf "
              "located in a worker process); fits/s counts from the first upload to the last record."]
    (RESULTS / "load.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
