"""MPI-parallel simpleFoam for the bridge: decomposition, ``mpirun``, reconstruction, killing every rank.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

What the bridge's pause (the FIFO fvSolution ``#include``s, foam_bridge._episode_case) does with N ranks,
measured on OpenFOAM v1912 and Open MPI 4.1.4 (pitzDaily in 2 subdomains, a pause after iteration 3,
2026-12-04):

- With ``fileModificationChecking timeStamp`` (what the serial bridge sets) *every* rank reads
  ``system/fvSolution`` itself and opens the FIFO: both ranks blocked in ``open()`` on it. One write
  then feeds one rank; the other reads EOF and runs with the case's own factors: silently different
  factors per rank. And the re-read after ``timeActivatedFileUpdate`` came one iteration late: only the
  master copies the file, the ranks' timestamps disagreed ("Delaying reading ... due to inconsistent
  file time-stamps between processors") and all re-read after iteration 4, not 3: a missed pause.
- With ``timeStampMaster`` (v1912's own default) fvSolution is a global file read by the master only;
  the master parses it, ``#include``s and all, and broadcasts the dictionary: only rank 0 opened the
  FIFO (rank 1 never did: a per-rank FIFO named by ``$OMPI_COMM_WORLD_RANK`` stayed unopened), once
  per read, and the re-read came exactly after iteration 3. So with N ranks the bridge sets
  ``timeStampMaster`` and the serial design holds unchanged: one FIFO per pause, one reader.
- ``fileHandler masterUncollated`` also has only the master read, but it opens every file twice (each
  FIFO had to be served twice per read); the bridge therefore sets ``fileHandler uncollated``.

Killing: Open MPI's mpirun puts every rank in a process group of its own (``setpgid``), inside mpirun's
session. A ``killpg`` of mpirun's group leaves the ranks; :func:`kill_session` SIGKILLs every process of
the session (and any descendant that left it) while mpirun, the session leader, is unreaped, so the
session id cannot have been reused. As a second line of defence each rank starts under ``setpriv
--pdeathsig KILL`` (util-linux; skipped where it is missing): the kernel kills a rank whose mpirun died,
as it kills mpirun whose bridge died (foam_bridge._solver's PR_SET_PDEATHSIG). Measured: after ``kill -9``
of ``mpirun -np 2 sleep 301`` both ranks still ran 5 s later; under setpriv none was left after 0.3 s.
simpleFoam's own ranks, MPI programs, ended 1.1 s after ``kill -9`` of their mpirun without it (they
notice the lost daemon): the two defences make that immediate, and cover a rank that does not notice.

Open MPI refuses to run as root unless asked (``--allow-run-as-root``) and refuses more ranks than cores
unless asked (``--oversubscribe``): the bridge passes both (the latter also makes waiting ranks yield
the core, which a paused run's ranks do).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import signal
import time
from pathlib import Path

from foam_bridge._errors import OpenFOAMNotFoundError
from foam_bridge._openfoam import INSTALL_HINT, OpenFOAM
from foam_bridge._template import run_application

__all__ = ["DECOMPOSE_DICT", "decompose", "kill_session", "mpirun_path", "processor_count", "reconstruct",
           "reconstruct_into", "reconstructed_case", "session_processes", "solver_command"]

DECOMPOSE_DICT = "decomposeParDict"
#: How long kill_session keeps looking for a rank that had not yet been seen (a rank mid-fork).
KILL_SETTLE_S = 0.2


def mpirun_path(openfoam: OpenFOAM) -> str:
    """mpirun on the installation's PATH; OpenFOAMNotFoundError (one line) if there is none."""
    found = shutil.which("mpirun", path=openfoam.path)
    if found is None:
        raise OpenFOAMNotFoundError(f"mpirun not found on PATH={openfoam.path!r}: --np needs MPI (Debian: "
                                    f"`sudo apt-get install -y openmpi-bin`) and {INSTALL_HINT}")
    return found


def solver_command(openfoam: OpenFOAM, case: Path, ranks: int) -> list[str]:
    """The command line of simpleFoam on ``case``: plain, or under mpirun with ``ranks`` ranks."""
    solver = [openfoam.executable("simpleFoam"), "-case", str(case)]
    if ranks <= 1:
        return solver
    root = ["--allow-run-as-root"] if os.geteuid() == 0 else []
    setpriv = shutil.which("setpriv", path=f"{openfoam.path}{os.pathsep}/usr/bin:/bin")
    dies_with_mpirun = [setpriv, "--pdeathsig", "KILL"] if setpriv else []
    return [mpirun_path(openfoam), "-np", str(ranks), "--oversubscribe", *root, *dies_with_mpirun, *solver,
            "-parallel"]


def processor_count(case: Path) -> int:
    """How many processor* directories (subdomains) the case holds (0: not decomposed)."""
    return sum(1 for path in case.glob("processor*") if re.fullmatch(r"processor\d+", path.name))


def decompose(case: Path, openfoam: OpenFOAM, ranks: int) -> None:
    """Decompose ``case`` into ``ranks`` subdomains (``decomposePar -force``): its own decomposeParDict
    when that one asks for ``ranks`` subdomains, else one that does (:func:`_write_decompose_dict`).
    decomposePar reads fvSolution: call it before the FIFO is #included. CaseError on failure."""
    _write_decompose_dict(case, ranks)
    run_application(openfoam, "decomposePar", case, "-force")


def _write_decompose_dict(case: Path, ranks: int) -> None:
    """Keep the case's decomposeParDict if it has ``ranks`` subdomains; otherwise write ``simple``
    splitting x into ``ranks`` slabs: the one method that needs no library (scotch and metis are
    stubs in some builds, Debian's v1912 among them) and no input but the count."""
    path = case / "system" / DECOMPOSE_DICT
    if path.is_file():
        found = re.search(r"^\s*numberOfSubdomains\s+(\d+)\s*;", path.read_text(), re.MULTILINE)
        if found is not None and int(found.group(1)) == ranks:
            return
    path.write_text("FoamFile { version 2.0; format ascii; class dictionary; object decomposeParDict; }\n"
                    f"// written by jaxsimrl solve --np {ranks}\nnumberOfSubdomains {ranks};\n"
                    f"method simple;\ncoeffs {{ n ({ranks} 1 1); delta 0.001; }}\n")


def reconstruct(case: Path, openfoam: OpenFOAM, time_name: str | None = None) -> None:
    """``reconstructPar`` of one time (default the latest) into ``case``'s top level. It reads fvSolution:
    ``case`` must not #include a FIFO. CaseError on failure."""
    which = ["-latestTime"] if time_name is None else ["-time", time_name]
    run_application(openfoam, "reconstructPar", case, *which)


def session_processes(leader: int) -> set[int]:
    """Every process in the session ``leader`` leads, and every descendant of one (which may have left
    it by ``setsid``), from /proc; the leader itself included while it exists."""
    sessions: dict[int, int] = {}
    parents: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        with contextlib.suppress(OSError, ValueError, IndexError):
            with open(f"/proc/{entry}/stat", "rb") as handle:
                fields = handle.read().rsplit(b")", 1)[1].split()
            parents[int(entry)], sessions[int(entry)] = int(fields[1]), int(fields[3])
    found = {pid for pid, sid in sessions.items() if sid == leader}
    grew = True
    while grew:
        more = {pid for pid, parent in parents.items() if parent in found} - found
        found |= more
        grew = bool(more)
    return found


def kill_session(leader: int) -> None:
    """SIGKILL every process of ``leader``'s session and their descendants (see the module docstring).
    The leader must be unreaped (a zombie keeps its id, so no other session can have it)."""
    deadline = time.monotonic() + KILL_SETTLE_S
    while True:
        found = session_processes(leader)
        for pid in found:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal.SIGKILL)
        if time.monotonic() >= deadline:
            return
        time.sleep(0.02)


def reconstruct_into(source: Path, dest: Path, openfoam: OpenFOAM, time_name: str | None = None,
                     mesh: bool = False) -> None:
    """Reconstruct the fields of one time (default the latest) of the decomposed ``source`` into
    ``dest``, a case with its own system/ (no FIFO #included) and constant/: ``source``'s processor*
    directories are linked into ``dest`` while reconstructPar reads them, then unlinked. ``mesh``: first
    the mesh too (``reconstructParMesh -constant``), for a ``dest`` without one."""
    links = []
    try:
        for processor in sorted(source.glob("processor*")):
            links.append(dest / processor.name)
            links[-1].symlink_to(processor.resolve())
        if mesh:
            # its default merge tolerance (1e-7) is refused for a case written with 6 digits (the default)
            run_application(openfoam, "reconstructParMesh", dest, "-constant", "-mergeTol", "1e-6")
        reconstruct(dest, openfoam, time_name)
    finally:
        for link in links:
            with contextlib.suppress(FileNotFoundError):
                link.unlink()


def reconstructed_case(episode: Path, system: Path, dest: Path, openfoam: OpenFOAM) -> Path:
    """``dest``: the decomposed ``episode``'s latest fields reconstructed, with the dictionaries of
    ``system`` (the user's own: the episode's fvSolution #includes FIFOs), the episode's mesh and its
    postProcessing/ (linked; the master writes it at the top level). Returns ``dest``."""
    shutil.rmtree(dest, ignore_errors=True)
    dest.mkdir(parents=True)
    shutil.copytree(system, dest / "system", symlinks=True)
    (dest / "constant").symlink_to((episode / "constant").resolve())
    if (episode / "postProcessing").is_dir():
        (dest / "postProcessing").symlink_to((episode / "postProcessing").resolve())
    reconstruct_into(episode, dest, openfoam)
    return dest
