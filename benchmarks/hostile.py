"""Hostile-input benchmark: each kind of request that once took the service down or
answered 500 (issue 19), sent to a real ``calf-nurbs serve`` on localhost with keys
required, measuring per request the time to its answer and the extra resident memory
of the whole server (the API process and its pool workers, sampled every 20 ms),
then two floods on a second service with the default rate limits: one clinic's
uploads (4 threads that ignore Retry-After) and one clinic's populations (a new grid
each), each while another clinic uploads a scan and waits for its record.

    .venv/bin/python benchmarks/hostile.py [REPEATS]

Writes benchmarks/results/hostile.json and hostile.md.  Targets (issue 19): every
hostile request answers 4xx within 2 s and under 300 MB of extra RSS; another clinic's
upload-to-record during a flood within 2x its idle time (medians of REPEATS).
"""

from __future__ import annotations

import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import httpx

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.hostile_inputs import LEG_STL, huge_coordinate_xyz, instanced_glb, leg_in_inches, obj_with_2d_vertices, tube_record  # noqa: E402
from benchmarks.served import BIN, free_port, start, stop, wait_ready  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
LEG = LEG_STL.read_bytes()


def tree_rss_mb(pid: int) -> float:
    """Resident memory of ``pid`` and all its descendants (MB), from /proc."""
    parents: dict[int, int] = {}
    rss: dict[int, float] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as handle:
                fields = handle.read().rsplit(")", 1)[1].split()
            parents[int(entry)] = int(fields[1])
            rss[int(entry)] = int(fields[21]) * os.sysconf("SC_PAGE_SIZE") / 2 ** 20
        except (OSError, IndexError, ValueError):
            continue
    tree, frontier = {pid}, [pid]
    while frontier:
        parent = frontier.pop()
        for child, its_parent in parents.items():
            if its_parent == parent and child not in tree:
                tree.add(child)
                frontier.append(child)
    return sum(rss.get(p, 0.0) for p in tree)


class PeakRss:
    """The server tree's peak RSS while the block runs (sampled every 20 ms)."""

    def __init__(self, pid: int):
        self.pid = pid

    def __enter__(self):
        self.baseline = tree_rss_mb(self.pid)
        self.peak = self.baseline
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def _sample(self):
        while not self._stop.is_set():
            self.peak = max(self.peak, tree_rss_mb(self.pid))
            self._stop.wait(0.02)

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, tree_rss_mb(self.pid))

    @property
    def extra_mb(self) -> float:
        return self.peak - self.baseline


def raw_post(port: int, head: bytes) -> tuple[int, float]:
    """A POST whose promised body is never sent: (status, seconds to the answer)."""
    started = time.perf_counter()
    with socket.create_connection(("127.0.0.1", port), timeout=30) as conn:
        conn.sendall(head)
        answer = conn.recv(65536)
    return int(answer.split(b" ", 2)[1]), time.perf_counter() - started


def upload_to_record(base: str, key: str, points: int) -> float:
    """Seconds from sending the leg to its record being stored."""
    headers = {"Authorization": f"Bearer {key}"}
    started = time.perf_counter()
    while True:  # a 429 (the clinic's own bounds) is retried as a portal would
        response = httpx.post(f"{base}/api/v1/scans", content=LEG, params={"points": points},
                              headers={**headers, "Content-Type": "model/stl"}, timeout=120)
        if response.status_code != 429:
            break
        time.sleep(float(response.headers.get("Retry-After", "1")))
    assert response.status_code == 202, response.text
    location = response.headers["location"]
    while True:
        job = httpx.get(f"{base}{location}", headers=headers, timeout=30).json()
        if job["status"] in ("succeeded", "failed"):
            assert job["status"] == "succeeded", job
            return time.perf_counter() - started
        time.sleep(0.05)


def new_key(env: dict, tenant: str, scopes: str = "upload,read,design") -> str:
    """A new API key of ``tenant`` on the service whose environment (data directory) is ``env``."""
    made = subprocess.run([str(BIN / "calf-nurbs"), "keys", "create", "--tenant", tenant, "--scopes", scopes],
                          env={**os.environ, **env}, capture_output=True, text=True, check=True)
    return made.stdout.strip().splitlines()[-1]


def main(repeats: int = 3) -> dict:
    data_dir = Path(tempfile.mkdtemp(prefix="calf-hostile-"))
    env = {"CALF_DATA_DIR": str(data_dir), "CALF_WORKERS": "2", "CALF_AUTH": "required",
           "CALF_UPLOAD_RATE_LIMIT": "0", "CALF_RATE_LIMIT": "0", "CALF_LOG_LEVEL": "WARNING"}

    hostile_key, other_key = (new_key(env, "hostile clinic"), new_key(env, "other clinic"))
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    server = start(["serve", "--port", str(port)], env)
    auth = {"Authorization": f"Bearer {hostile_key}"}
    rows = []
    try:
        wait_ready(base, server)
        upload_to_record(base, other_key, 15)  # warm: both pools' workers started
        rid = httpx.post(f"{base}/api/v1/records", json=tube_record(24, 10, 3), headers=auth).json()["id"]
        stl = {"Content-Type": "model/stl"}
        big_json = json.dumps(tube_record(253, 256, 5)).encode()
        cases = {
            "import 253x256 quintic net (4 MB JSON)": lambda: httpx.post(
                f"{base}/api/v1/records", content=big_json, headers={**auth, "Content-Type": "application/json"}, timeout=60),
            "import 48x48 quintic net": lambda: httpx.post(f"{base}/api/v1/records", json=tube_record(48, 48, 5), headers=auth, timeout=60),
            "import 4 m tall tube": lambda: httpx.post(f"{base}/api/v1/records", json=tube_record(16, 8, 3, height_mm=1990.0), headers=auth, timeout=60),
            "import zero-radius tube": lambda: httpx.post(f"{base}/api/v1/records", json=tube_record(16, 8, 3, radius_mm=0.0, circumference_mm=300.0), headers=auth, timeout=60),
            "GLB instancing the leg 140 times": lambda: httpx.post(f"{base}/api/v1/scans", content=instanced_glb(140), headers={**auth, "Content-Type": "model/gltf-binary"}, timeout=120),
            "GLB instancing the leg 400 times": lambda: httpx.post(f"{base}/api/v1/scans", content=instanced_glb(400), headers={**auth, "Content-Type": "model/gltf-binary"}, timeout=120),
            "100 MB JSON without a key": lambda: httpx.post(f"{base}/api/v1/records", content=b" " * (100 * 2 ** 20), headers={"Content-Type": "application/json"}, timeout=120),
            "'{bad' without a key": lambda: httpx.post(f"{base}/api/v1/records", content=b"{bad", headers={"Content-Type": "application/json"}),
            "OBJ with 2-D vertices": lambda: httpx.post(f"{base}/api/v1/scans", content=obj_with_2d_vertices(), headers={**auth, "Content-Type": "model/obj"}, timeout=60),
            "600 XYZ rows of 1e308 i 1e308": lambda: httpx.post(f"{base}/api/v1/scans", content=huge_coordinate_xyz(), headers={**auth, "Content-Type": "chemical/x-xyz"}, timeout=60),
            "leg in inches": lambda: httpx.post(f"{base}/api/v1/scans", content=leg_in_inches(), headers={**auth, **stl}, timeout=60),
            "design with resolution_mm 1e-310": lambda: httpx.post(f"{base}/api/v1/records/{rid}/designs", json={"fabric": {"stiffness_n_per_cm": 10}, "resolution_mm": 1e-310}, headers=auth),
            "fabric table of 100k rows": lambda: httpx.post(f"{base}/api/v1/records/{rid}/designs", content=json.dumps({"fabric": {"table": [[i / 1e5, i / 1e4] for i in range(100_000)]}}).encode(), headers={**auth, "Content-Type": "application/json"}, timeout=60),
        }
        for name, send in cases.items():
            times, extras, statuses = [], [], set()
            for _ in range(repeats):
                with PeakRss(server.pid) as rss:
                    started = time.perf_counter()
                    response = send()
                    times.append(time.perf_counter() - started)
                extras.append(rss.extra_mb)
                statuses.add(f"{response.status_code} {response.json().get('code', '')}")
            rows.append({"request": name, "answers": sorted(statuses), "median_s": statistics.median(times),
                         "max_s": max(times), "median_extra_rss_mb": statistics.median(extras), "max_extra_rss_mb": max(extras)})
        for name, head in {
            "Content-Length 3000000000 (upload, never sent)": f"POST /api/v1/scans HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {hostile_key}\r\nContent-Type: model/stl\r\nContent-Length: 3000000000\r\n\r\n".encode(),
            "Content-Length 500000 without a key (never sent)": b"POST /api/v1/records HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: 500000\r\n\r\n",
        }.items():
            with PeakRss(server.pid) as rss:
                status, seconds = raw_post(port, head)
            rows.append({"request": name, "answers": [str(status)], "median_s": seconds, "max_s": seconds,
                         "median_extra_rss_mb": rss.extra_mb, "max_extra_rss_mb": rss.extra_mb})
        # the largest accepted import, measured and compared (a bounded, successful request)
        tall = httpx.post(f"{base}/api/v1/records", json=tube_record(72, 40, 3, height_mm=1150.0), headers=auth).json()["id"]
        for name, path in {"measurements of the largest accepted import": f"/api/v1/records/{tall}/measurements?heights=100,600,1000",
                           "compare of the largest accepted import with itself": f"/api/v1/records/{tall}/compare/{tall}"}.items():
            times, extras = [], []
            for _ in range(repeats):
                with PeakRss(server.pid) as rss:
                    started = time.perf_counter()
                    response = httpx.get(f"{base}{path}", headers=auth, timeout=120)
                    times.append(time.perf_counter() - started)
                extras.append(rss.extra_mb)
            rows.append({"request": name, "answers": [str(response.status_code)], "median_s": statistics.median(times),
                         "max_s": max(times), "median_extra_rss_mb": statistics.median(extras), "max_extra_rss_mb": max(extras)})
    finally:
        stop(server)
    # the floods on a service with its default rate limits: what bounds a clinic that
    # ignores Retry-After is the service's limits, not its manners
    flood_env = {k: v for k, v in env.items() if "RATE" not in k}
    flood_env["CALF_DATA_DIR"] = str(data_dir / "floods")
    (data_dir / "floods").mkdir()
    hostile_key, other_key = (new_key(flood_env, "hostile clinic"), new_key(flood_env, "other clinic"))
    port = free_port()
    base = f"http://127.0.0.1:{port}"
    server = start(["serve", "--port", str(port)], flood_env)
    try:
        wait_ready(base, server)
        upload_to_record(base, other_key, 15)  # warm
        floods = flood_runs(base, hostile_key, other_key, repeats, server.pid)
    finally:
        stop(server)
    result = {"repeats": repeats, "requests": rows, "floods": floods}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "hostile.json").write_text(json.dumps(result, indent=2))
    (RESULTS / "hostile.md").write_text(report(result))
    return result


def flood_runs(base: str, hostile_key: str, other_key: str, repeats: int, pid: int) -> list[dict]:
    """Another clinic's upload-to-record, idle and while the hostile clinic floods."""
    idle = [upload_to_record(base, other_key, 9 + i % 4) for i in range(repeats)]
    out = []
    hostile = {"Authorization": f"Bearer {hostile_key}"}

    def upload_flood(stop_at: threading.Event) -> None:
        n = 0
        while not stop_at.is_set():
            httpx.post(f"{base}/api/v1/scans", content=LEG, params={"points": 4 + n % 30},
                       headers={**hostile, "Content-Type": "model/stl"}, timeout=120)
            n += 1

    record_ids = []
    for points in (8, 15):
        job = httpx.post(f"{base}/api/v1/scans", content=LEG, params={"points": points},
                         headers={**hostile, "Content-Type": "model/stl"}, timeout=120).headers["location"]
        while (state := httpx.get(f"{base}{job}", headers=hostile).json())["status"] not in ("succeeded", "failed"):
            time.sleep(0.05)
        record_ids.append(state["record_id"])

    def population_flood(stop_at: threading.Event) -> None:
        n = 0
        while not stop_at.is_set():
            grid = f"{5 + n % 30}x{8 + n % 60}"
            httpx.post(f"{base}/api/v1/populations", json={"record_ids": record_ids, "grid": grid}, headers=hostile, timeout=60)
            n += 1

    for name, flood, threads in (("4 threads of uploads", upload_flood, 4), ("populations, a new grid each", population_flood, 2)):
        stop_at = threading.Event()
        workers = [threading.Thread(target=flood, args=(stop_at,), daemon=True) for _ in range(threads)]
        for w in workers:
            w.start()
        time.sleep(3.0)  # the flood has filled the clinic's queue
        with PeakRss(pid) as rss:
            during = [upload_to_record(base, other_key, 9 + i % 4) for i in range(repeats)]
        stop_at.set()
        for w in workers:
            w.join(timeout=180)
        usage = httpx.get(f"{base}/api/v1/usage", headers=hostile).json()
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:  # let the hostile clinic's queue drain before the next flood
            usage = httpx.get(f"{base}/api/v1/usage", headers=hostile).json()
            if not usage["jobs"]["queued"] and not usage["jobs"]["running"]:
                break
            time.sleep(0.5)
        out.append({"flood": name, "idle_median_s": statistics.median(idle), "during_median_s": statistics.median(during),
                    "ratio": statistics.median(during) / statistics.median(idle), "server_peak_rss_mb": rss.peak})
    return out


def report(result: dict) -> str:
    lines = ["# Hostile inputs (issue 19)", "",
             f"`.venv/bin/python benchmarks/hostile.py {result['repeats']}`: a `calf-nurbs serve` on localhost, keys "
             "required, 2 workers; each request sent "
             f"{result['repeats']} times; extra RSS is the peak of the server's whole process tree (API and pool "
             "workers) above its level before the request. Targets: 4xx within 2 s, under 300 MB extra.", "",
             "| request | answer | median s | max s | median extra RSS MB | max extra RSS MB |", "|---|---|---|---|---|---|"]
    for row in result["requests"]:
        lines.append(f"| {row['request']} | {', '.join(row['answers'])} | {row['median_s']:.3f} | {row['max_s']:.3f} | "
                     f"{row['median_extra_rss_mb']:.0f} | {row['max_extra_rss_mb']:.0f} |")
    lines += ["", "Another clinic's upload-to-record (the real leg, 27k triangles) idle and while the hostile clinic "
              "floods (target: within 2x):", "", "| flood | idle median s | during median s | ratio | server peak RSS MB |",
              "|---|---|---|---|---|"]
    for row in result["floods"]:
        lines.append(f"| {row['flood']} | {row['idle_median_s']:.2f} | {row['during_median_s']:.2f} | "
                     f"{row['ratio']:.2f} | {row['server_peak_rss_mb']:.0f} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(report(main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)))
