"""The lock that gives one FoamCaseEnv its env directory: an exclusive ``fcntl.flock`` on a file in it,
held until the env closes (or its process dies), so that two envs never build in one directory.

Internal to foam_bridge; names here may change.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
from pathlib import Path
from typing import BinaryIO

#: Lock file held (fcntl.flock) by the FoamCaseEnv that owns an env directory.
LOCK_FILE = ".foam_bridge.lock"


def claim_directory(root: Path) -> BinaryIO:
    """Create ``root`` and take the exclusive lock on its LOCK_FILE; returns the open lock file.

    One-line ValueError if another live FoamCaseEnv holds it. The lock lives as long as the file
    object (closed by close(), by garbage collection, or by the kernel when the process dies). If the
    owner removed the directory between our open and our lock (its close()), the lock is on a dead
    file: retry on the new one.
    """
    while True:
        root.mkdir(parents=True, exist_ok=True)
        path = root / LOCK_FILE
        try:
            lock = open(path, "ab")  # noqa: SIM115 (held until FoamCaseEnv.close)
        except FileNotFoundError:
            continue  # the directory vanished under us
        try:
            fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock.close()
            raise ValueError(f"env directory {root} is in use by another FoamCaseEnv (same work_dir "
                             f"and env_id); give each env its own env_id or work_dir") from None
        with contextlib.suppress(FileNotFoundError):
            if os.path.samestat(os.fstat(lock.fileno()), os.stat(path)):
                return lock
        lock.close()
