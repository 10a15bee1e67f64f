"""`calf-nurbs` processes on localhost, for the benchmarks and the tests that need the
service as deployed (serve, worker): a free port, start, wait until ready, stop.

A process's output goes to a temporary file, not a pipe: nobody reads a pipe while the
process runs, and a service that logs a line per request would block once the pipe's
64 KiB buffer is full.  The file is read when the process has died, for the error.
"""

from __future__ import annotations

import contextlib
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import httpx

BIN = Path(sys.executable).parent


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start(args: list[str], env: dict, cwd: Path | None = None) -> subprocess.Popen:
    """``calf-nurbs ARGS`` with ``env`` over this process's environment, in ``cwd`` (this
    process's own when None)."""
    log = tempfile.TemporaryFile(mode="w+")
    process = subprocess.Popen([str(BIN / "calf-nurbs"), *args], env={**os.environ, **env}, cwd=cwd,
                               stdout=log, stderr=subprocess.STDOUT, text=True)
    process.log = log  # type: ignore[attr-defined]
    return process


def output(process: subprocess.Popen) -> str:
    log = getattr(process, "log", None)
    if log is None:
        return ""
    log.seek(0)
    return log.read()


def wait_ready(base: str, process: subprocess.Popen, timeout: float = 60.0) -> None:
    """Until ``base``/readyz answers 200; raises with the process's output if it exits."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if process.poll() is not None:
            raise RuntimeError(f"server exited: {output(process)[-4000:]}")
        try:
            if httpx.get(f"{base}/readyz", timeout=2).status_code == 200:
                return
        except httpx.TransportError:
            pass
        time.sleep(0.2)
    raise RuntimeError("the server did not become ready")


def stop(*processes: subprocess.Popen) -> None:
    """SIGTERM, then SIGKILL after 30 s."""
    for process in processes:
        process.terminate()
    for process in processes:
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
        log = getattr(process, "log", None)
        if log is not None:
            log.close()


@contextlib.contextmanager
def served_with_key(data_dir: Path, tenant: str, scopes: str = "admin"):
    """A ``calf-nurbs serve`` on a free port with keys required, on ``data_dir``, and a
    new key of ``tenant``: yields (base URL, key); stopped on exit."""
    env = {"CALF_DATA_DIR": str(data_dir), "CALF_WORKERS": "1", "CALF_AUTH": "required",
           "CALF_UPLOAD_RATE_LIMIT": "0", "CALF_RATE_LIMIT": "0", "CALF_LOG_LEVEL": "WARNING"}
    created = subprocess.run([str(BIN / "calf-nurbs"), "keys", "create", "--tenant", tenant, "--scopes", scopes],
                             env={**os.environ, **env}, capture_output=True, text=True, check=True)
    key = created.stdout.strip().splitlines()[-1]
    port = free_port()
    server = start(["serve", "--port", str(port)], env)
    base = f"http://127.0.0.1:{port}"
    try:
        wait_ready(base, server)
        yield base, key
    finally:
        stop(server)
