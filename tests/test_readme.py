"""The README's walkthrough run as a newcomer runs it: its shell blocks that talk to the
service (`$AUTH` in them) and the command line's design block, in the README's order,
pasted into one bash against `calf-nurbs serve` (what `make run` starts) in an empty
folder holding only `.venv` and `tests/data`, as the repository root does.  The only
change to the text is the port (127.0.0.1:8000 -> a free one).  Every file the blocks
write (calf.stl, rec.json, order.pdf, leg.json, fabric.csv, ...) lands in that folder.

Left out, and why: `make run` / `make test` (this is what they serve and test), the
command-line block that starts `serve` and `worker` (long-running), the key block whose
`keys revoke cnk_1a2b3c4d` names a made-up prefix, and the scale-out block (PostgreSQL and
Redis hosts of its own; tests/jobs/test_dramatiq.py runs that set-up)."""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

from benchmarks.served import free_port, output, start, stop, wait_ready

#: end to end and slow: `make test-slow` (and .ci/run) runs it, `make test` does not
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]


def walkthrough_blocks(readme: str) -> list[str]:
    """The README's ``sh``/``bash`` blocks a newcomer pastes against a running service:
    those sending the clinic's key (``$AUTH``), and the command line's design block."""
    blocks = re.findall(r"^```(?:sh|bash)\n(.*?)^```", readme, flags=re.S | re.M)
    return [b for b in blocks if "$AUTH" in b or "calf-nurbs design" in b]


@pytest.fixture
def newcomer_folder(tmp_path: Path) -> Path:
    """An empty folder laid out as the repository root is for the README's paths: the
    installed `.venv` and `tests/data` linked in, nothing else."""
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "data").symlink_to(ROOT / "tests" / "data")
    (tmp_path / ".venv").symlink_to(ROOT / ".venv")
    return tmp_path


def test_the_readmes_walkthrough_works_as_written(newcomer_folder):
    if not (ROOT / ".venv" / "bin" / "calf-nurbs").exists():
        pytest.skip("no .venv in the repository root: `make test-slow` creates it")
    blocks = walkthrough_blocks((ROOT / "README.md").read_text())
    assert len(blocks) >= 5, "the README's walkthrough blocks were not found"
    port = free_port()
    script = "\n".join(blocks).replace("127.0.0.1:8000", f"127.0.0.1:{port}")
    server = start(["serve", "--host", "127.0.0.1", "--port", str(port)], {"CALF_WORKERS": "1"},
                   cwd=newcomer_folder)
    try:
        wait_ready(f"http://127.0.0.1:{port}", server)
        run = subprocess.run(["timeout", "600", "bash", "-c", script], cwd=newcomer_folder, capture_output=True,
                             text=True, env={k: v for k, v in os.environ.items() if not k.startswith("CALF_")})
    finally:
        server_said = output(server)
        stop(server)
    said = run.stdout + run.stderr
    assert run.returncode != 124, f"the walkthrough did not finish in 10 minutes:\n{said[-3000:]}"
    for failure in ("Traceback", "Internal Server Error", "command not found", "No such file", "KeyError",
                    "urn:calf-nurbs:problem:internal"):
        assert failure not in said, f"{failure!r} in the walkthrough's output:\n{said[-3000:]}\n{server_said[-2000:]}"
    # the upload answers 202 with the job to follow; the job ends as a record
    assert re.search(r"^202 /api/v1/jobs/\S+$", run.stdout, flags=re.M), run.stdout[:2000]
    assert '"status":"succeeded"' in run.stdout.replace(" ", "")
    # import 201, delete 204; the retried upload answered once and replayed once
    assert re.search(r"^201$", run.stdout, flags=re.M) and re.search(r"^204$", run.stdout, flags=re.M)
    assert len(re.findall(r"^HTTP/1.1 2\d\d", run.stdout, flags=re.M)) == 2
    assert re.search(r"^idempotent-replayed: true", run.stdout, flags=re.M | re.I)
    assert "calf_jobs_total" in run.stdout
    # the case erased, answering what it removed as the README says it does
    said_erased = re.search(r'^# (\{"scans":.*?\})', "\n".join(blocks), flags=re.M)
    assert said_erased, "the README no longer shows what erasing a case answers"
    assert re.search(rf"^{re.escape(said_erased.group(1))}$", run.stdout, flags=re.M), run.stdout[-3000:]
    # designs: the knitting specification, the refusal of an unreachable fabric, the order
    assert "unreachable_pressure" in run.stdout
    # size charts: the shipped examples listed, a CSV chart registered and decided on
    assert "'example-ansur2-ad', 'example-ansur2-ag'" in run.stdout
    assert re.search(r"^(ready_to_wear|made_to_measure|not_measured) ", run.stdout, flags=re.M), run.stdout[-3000:]
    for pdf in ("order.pdf",):
        assert (newcomer_folder / pdf).read_bytes()[:5] == b"%PDF-"
    for written in ("calf.stl", "calf.glb", "rec.json", "pressure.glb", "pressure.png", "leg.json", "fabric.csv"):
        assert (newcomer_folder / written).stat().st_size > 0, written
    assert run.returncode == 0, said[-3000:]
