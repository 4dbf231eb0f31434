"""Make the result of a bridge-driven run a normal OpenFOAM case again.

An episode case (foam_bridge._episode_case) holds the bridge's machinery: ``#include`` lines appended to the
user's controlDict and fvSolution, FIFOs (``system/foamBridge/relaxation.<K>``) that block any reader
(``foamDictionary -entry relaxationFactors system/fvSolution`` hangs on them), pause copies of
fvSolution and a symlinked mesh. :func:`export_case` writes what a user expects instead: their own
case as they gave it (``system/``, ``constant/``, ``0/``, scripts; never re-serialised, copied from the
source), the mesh as a real directory, the run's last time directory (its fields), its solver log and
what the case's own function objects wrote (``postProcessing/``). A run restarted from a later time
(FoamEnvConfig.start_time) keeps that time directory too, as the user gave it.
Nothing of the bridge remains, so ``foamDictionary``, ``paraFoam`` and a ``simpleFoam`` restart work as
on any case.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from foam_bridge._episode_case import STATE_FIELD
from foam_bridge._fields import time_directories
from foam_bridge._template import copy_case

__all__ = ["LOG_NAME", "POST_PROCESSING", "export_case", "latest_time"]

#: The solver log of the run, as written by foam_bridge._solver.
LOG_NAME = "log.simpleFoam"
POST_PROCESSING = "postProcessing"


def export_case(episode: Path, source: Path, out: Path, log: Path | None = None, start_time: float = 0
                ) -> str | None:
    """Write into ``out`` the user's case ``source`` with the episode's results; returns the name of the
    time directory copied (None if the episode wrote no time after ``start_time``, the time the run
    started from: that one is copied from ``source``).

    ``out`` may exist (its other files stay; the case's entries are replaced). ``log``: the solver log to
    keep (default the episode's). The copy goes to a sibling temporary directory first, then each entry
    is moved into place, so a half-written case is never left under the final names.
    """
    out.mkdir(parents=True, exist_ok=True)
    staging = out.parent / f".{out.name}.export"
    copy_case(Path(source), staging, mesh=True, start_time=start_time)
    mesh = staging / "constant" / "polyMesh"
    if not (mesh / "boundary").is_file():  # meshed by the bridge (blockMesh): the run's own mesh
        shutil.rmtree(mesh, ignore_errors=True)
        shutil.copytree((episode / "constant" / "polyMesh").resolve(), mesh)
    latest = latest_time(episode, start_time)
    if latest is not None:
        shutil.copytree(latest, staging / latest.name)
        for leftover in (staging / latest.name).glob(f"{STATE_FIELD}*"):
            leftover.unlink()
    log = log if log is not None else episode / LOG_NAME
    if log.is_file():
        shutil.copy2(log, staging / LOG_NAME)
    if (episode / POST_PROCESSING).is_dir():  # the case's own function objects (the bridge's write nothing)
        shutil.copytree(episode / POST_PROCESSING, staging / POST_PROCESSING)
    for entry in sorted(staging.iterdir()):
        target = out / entry.name
        if target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        os.replace(entry, target)
    staging.rmdir()
    return None if latest is None else latest.name


def latest_time(case: Path, after: float = 0) -> Path | None:
    """The case's latest time directory after ``after`` (a finished run's fields), None if there is none."""
    times = [path for value, path in time_directories(case) if value > after]
    return times[-1] if times else None
