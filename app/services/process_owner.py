"""Which process holds a reservation, and whether it is still alive.

An owner is ``host:pid:tag``; the tag is drawn once per process, so that a process that
restarted under the same pid (pid 1 of a container) is told from its dead predecessor.
On this host the answer is certain: a pid that no longer exists, or our own pid with
another tag, is a dead owner.  Another host's process cannot be asked: None.
"""

from __future__ import annotations

import os
import socket
import uuid

PROCESS_TAG = uuid.uuid4().hex[:8]


def this_process() -> str:
    return f"{socket.gethostname()}:{os.getpid()}:{PROCESS_TAG}"


def owner_is_dead(owner: str | None) -> bool | None:
    """True when ``owner`` was a process of this host that has ended, False when it is
    alive, None when it cannot be told (another host, or no owner recorded)."""
    if not owner:
        return None
    host, _, rest = owner.partition(":")
    pid_text, _, tag = rest.partition(":")
    if host != socket.gethostname() or not pid_text.isdigit():
        return None
    pid = int(pid_text)
    if pid == os.getpid():
        return tag != PROCESS_TAG
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except PermissionError:  # alive, another user's
        return False
    return False
