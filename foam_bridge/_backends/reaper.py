"""Killing solver processes orphaned by a dead worker.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

The solver runs in its own session (its own process group), so when its worker is SIGKILLed the
solver survives, reparented to init, possibly blocked forever at a pause point. It is found by the
mark the bridge puts in the environment of every OpenFOAM process it starts
(foam_bridge._openfoam.BRIDGE_MARK = the case directory, inherited by the process's children): a process
whose initial environment (``/proc/PID/environ``, which the process cannot change) marks a case under
the env's directory belongs to that env. A process the bridge did not start is never touched, whatever
its working directory or command line: a user's shell ``cd``-ed into a kept case, paraFoam opened on
it. A marked process that leads its group (the solver: ``start_new_session``) is killed with its whole
group; any other marked process alone. Linux only (/proc).
"""

from __future__ import annotations

import contextlib
import os
import signal
from pathlib import Path

from foam_bridge._openfoam import BRIDGE_MARK

__all__ = ["kill_processes_under", "processes_under"]

_MARK = BRIDGE_MARK.encode() + b"="


def _marked_under(pid: int, root: str) -> bool:
    """Whether the bridge started ``pid`` (or its ancestor) for a case in ``root`` or below."""
    with contextlib.suppress(OSError), open(f"/proc/{pid}/environ", "rb") as handle:
        for entry in handle.read().split(b"\0"):
            if entry.startswith(_MARK):
                case = entry[len(_MARK):].decode(errors="replace")
                return case == root or case.startswith(root + os.sep)
    return False


def processes_under(path: Path) -> list[int]:
    """Pids of the processes the bridge started for a case in ``path`` or below (never this one or its
    parent)."""
    if not os.path.exists(path):
        return []
    root = os.path.realpath(path)
    spared = {os.getpid(), os.getppid()}  # never the caller or the driver that started it
    pids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit() and int(entry) not in spared and _marked_under(int(entry), root):
            pids.append(int(entry))
    return pids


def kill_processes_under(path: Path) -> int:
    """SIGKILL the processes found by ``processes_under``: the whole group of one that leads its group
    (never our own group), any other alone. Returns the count."""
    marked = processes_under(path)
    own_group = os.getpgrp()
    killed = 0
    for pid in marked:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            group = os.getpgid(pid)
            if group == pid and group != own_group:  # a group the bridge started: its solver's session
                os.killpg(group, signal.SIGKILL)
            else:
                os.kill(pid, signal.SIGKILL)
            killed += 1
    return killed
