"""``solve --np N``: the case run by N MPI ranks (foam_bridge._parallel has the bridge's side).

What the user gets is what a parallel run of their own leaves after ``reconstructPar``: ``out`` holds the
reconstructed case (and, with ``keep_decomposed``, the ranks' processor* directories too). A decomposed
CASE (processor* directories) is taken when it has N of them: its top-level fields are where the run
starts, reconstructed first into a copy when its processor directories hold a later time than the
top level (a parallel run that went on). The run decomposes the case again with the case's own
decomposeParDict (it asks for N subdomains), which makes the same subdomains for a deterministic method.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from foam_bridge import (
    find_openfoam,
    mpirun_path,
    processor_count,
    reconstruct_into,
    reconstructed_case,
    time_directories,
)

__all__ = ["INPUT_DIR", "check_ranks", "export_source", "keep_processors", "prepared_input",
           "runs_side_by_side"]

#: Where a decomposed case's later time is reconstructed (inside ``out``; removed at the end).
INPUT_DIR = ".solve-input"


def check_ranks(case: Path, ranks: int | None) -> int:
    """The rank count to run ``case`` with (1: serial); one-line ValueError for a decomposed case without
    ``--np`` or with another count, OpenFOAMNotFoundError when ``--np`` > 1 finds no mpirun."""
    found = processor_count(case)
    if ranks is None or ranks == 1:
        if found:
            hint = f"give --np {found} to run it in parallel, or " if found > 1 else ""
            raise ValueError(f"case {case} is decomposed into {found} subdomains (processor* directories): "
                             f"{hint}reconstruct it (reconstructPar)")
        return 1
    if ranks < 1:
        raise ValueError(f"--np must be >= 1, got {ranks}")
    if found and found != ranks:
        raise ValueError(f"case {case} is decomposed into {found} subdomains, not --np {ranks}: give --np "
                         f"{found}, or reconstruct it (reconstructPar) and solve it with --np {ranks}")
    mpirun_path(find_openfoam())
    return ranks


def prepared_input(case: Path, out: Path) -> Path:
    """The case a decomposed ``case`` is solved from: itself, or (when its processor directories hold a
    later time than its top level) a copy in ``out/INPUT_DIR`` with that time reconstructed (and the mesh,
by reconstructParMesh, if its top level has none: decomposePar's input may have been removed)."""
    if not processor_count(case):
        return case
    top = [value for value, _ in time_directories(case)]
    ranks = [(value, path) for value, path in time_directories(case / "processor0")]
    if not ranks or (top and ranks[-1][0] <= top[-1]):
        return case
    copy = out / INPUT_DIR / case.name
    shutil.copytree(case, copy, ignore=shutil.ignore_patterns("processor*", "log.*"))
    meshed = (copy / "constant" / "polyMesh" / "boundary").is_file()
    reconstruct_into(case, copy, find_openfoam(), ranks[-1][1].name, mesh=not meshed)
    return copy


def runs_side_by_side(ranks: int) -> bool:
    """Whether the comparison runs beside the controlled one: only when both get a core per rank (the
    ranks of two oversubscribed runs would time-share cores, and their times would measure that)."""
    return len(os.sched_getaffinity(0)) >= 2 * ranks


def export_source(episode: Path, case: Path, work: Path, ranks: int) -> Path:
    """The case directory export_case copies the controlled run's result from: the episode, or its
    latest fields reconstructed into ``work/reconstructed`` (the case's own system/ dictionaries)."""
    if ranks <= 1:
        return episode
    return reconstructed_case(episode, case / "system", work / "reconstructed", find_openfoam())


def keep_processors(run_case: Path, out: Path) -> None:
    """Copy the run's processor* directories (mesh, initial and final fields) into ``out``."""
    for processor in sorted(run_case.glob("processor*")):
        shutil.copytree(processor, out / processor.name, symlinks=False, dirs_exist_ok=True)
