"""Killing solver processes orphaned by a dead worker.

The solver runs in its own session (its own process group), so when its worker is SIGKILLed the
solver survives, reparented to init, possibly blocked forever at a pause point. It is found by its
case directory: any process whose working directory lies under the env's directory, or whose command
line names it, belongs to that env. Its whole process group is killed. Linux only (/proc).
"""

from __future__ import annotations

import contextlib
import os
import signal
from pathlib import Path


def _mentions(pid: int, root: str) -> bool:
    with contextlib.suppress(OSError):
        cwd = os.readlink(f"/proc/{pid}/cwd")
        if cwd == root or cwd.startswith(root + os.sep):
            return True
    with contextlib.suppress(OSError), open(f"/proc/{pid}/cmdline", "rb") as handle:
        args = handle.read().decode(errors="replace").split("\0")
        return any(arg == root or arg.startswith(root + os.sep) for arg in args)
    return False


def processes_under(path: Path) -> list[int]:
    """Pids of processes running in, or naming, ``path`` or below (never this one or its parent)."""
    if not os.path.exists(path):
        return []
    root = os.path.realpath(path)
    spared = {os.getpid(), os.getppid()}  # never the caller or the driver that started it
    pids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit() and int(entry) not in spared and _mentions(int(entry), root):
            pids.append(int(entry))
    return pids


def kill_processes_under(path: Path) -> int:
    """SIGKILL every process group found by ``processes_under`` (never our own group); returns the count."""
    own_group = os.getpgrp()
    killed = 0
    for pid in processes_under(path):
        with contextlib.suppress(ProcessLookupError, PermissionError):
            group = os.getpgid(pid)
            if group == own_group:
                os.kill(pid, signal.SIGKILL)
            else:
                os.killpg(group, signal.SIGKILL)
            killed += 1
    return killed
