"""Content-addressed storage of original scans on disk.

A scan is written to a temporary file while it is received and hashed, then moved to
``<data_dir>/scans/<sha256[:2]>/<sha256>`` with an atomic rename.  The same bytes are
stored once, however often they are uploaded; a stored file is never overwritten.
"""

from __future__ import annotations

import os
import socket
import tempfile
import time
from pathlib import Path

_HOST = socket.gethostname().replace("-", "_")


def _running(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class ScanStore:
    """The stored scans (``root``), the uploads being received (``tmp``) and the legs
    the upload check cut out of them (``placed``, one file per queued job: see
    :mod:`app.services.placed_legs`)."""

    def __init__(self, root: Path, tmp: Path, placed: Path):
        self.root = root
        self.tmp = tmp
        self.placed = placed
        for folder in (self.root, self.tmp, self.placed):
            folder.mkdir(parents=True, exist_ok=True)

    def path_for(self, sha256: str) -> Path:
        return self.root / sha256[:2] / sha256

    def new_temp(self) -> tuple[int, Path]:
        """A temporary file for an upload being received, named after the process that
        receives it (``upload-<host>-<pid>-...``), so that a crash's leftovers are known."""
        fd, name = tempfile.mkstemp(prefix=f"upload-{_HOST}-{os.getpid()}-", dir=self.tmp)
        return fd, Path(name)

    def exists(self, sha256: str) -> bool:
        return self.path_for(sha256).is_file()

    def commit(self, temp: Path, sha256: str) -> tuple[Path, bool]:
        """Move a received file into place; returns (path, newly_stored)."""
        final = self.path_for(sha256)
        if final.is_file():
            temp.unlink(missing_ok=True)
            return final, False
        final.parent.mkdir(parents=True, exist_ok=True)
        os.chmod(temp, 0o440)
        os.replace(temp, final)
        return final, True

    def clean_temp(self, older_than_s: float) -> int:
        """Remove the temporary upload files a crash left behind; returns how many: those
        of a process of this host that is no longer running, and any older than
        ``older_than_s`` (another host's, whose processes cannot be asked; an upload
        takes minutes at most)."""
        cutoff = time.time() - older_than_s
        removed = 0
        for path in self.tmp.glob("upload-*"):
            parts = path.name.split("-")
            ours = len(parts) >= 4 and parts[1] == _HOST and parts[2].isdigit()
            try:
                if (ours and not _running(int(parts[2]))) or path.stat().st_mtime < cutoff:
                    path.unlink()
                    removed += 1
            except FileNotFoundError:
                pass
        return removed

    def remove(self, sha256: str) -> None:
        """Undo a commit whose database row could not be written."""
        self.path_for(sha256).unlink(missing_ok=True)

    @staticmethod
    def placed_leg_temp(upload_temp: Path) -> Path:
        """Where the check of the upload received at ``upload_temp`` writes the leg it
        cut out: beside it, named like it (a crash's leftover goes with
        :meth:`clean_temp`)."""
        return upload_temp.with_name(upload_temp.name + ".leg.npz")

    def placed_leg_path(self, job_id: str) -> Path:
        """The leg cut out for job ``job_id`` (a job id is a uuid: no path in it)."""
        return self.placed / f"{job_id}.npz"

    def keep_placed_leg(self, temp: Path, job_id: str) -> None:
        """Hand the leg a check wrote at ``temp`` to job ``job_id`` (an atomic rename)."""
        try:
            os.replace(temp, self.placed_leg_path(job_id))
        except FileNotFoundError:  # the check wrote none: the fit reads the scan
            pass

    def remove_placed_legs(self, job_ids) -> int:
        """Remove the legs kept for ``job_ids`` (jobs erased before they ran); returns
        how many there were."""
        removed = 0
        for job_id in job_ids:
            try:
                self.placed_leg_path(job_id).unlink()
                removed += 1
            except FileNotFoundError:
                pass
        return removed
