"""The built-in case (the paper's backward-facing step, OpenFOAM's backwardFacingStep2D tutorial) and
the meshing steps every case shares: copying a case without its results, blockMesh, reading the mesh.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

The template lives in ``foam_bridge/cases/backward_facing_step``; its ``system/meshParameters`` holds the
block cell counts and the floor height that :func:`mesh_parameters` computes from ``mesh_scale`` and
the step height.

Inlet turbulence of the built-in case (the paper's values: intensity I = 6.1e-4, nu_t/nu = 0.009,
nu = 1.56e-5 m^2/s from its transportProperties): ``k = 1.5 (I U)^2`` and ``omega = k / nu_t`` with
``nu_t = 0.009 nu``. (The tutorial's omega, 181728, does not follow this formula; we follow the paper.)
"""

from __future__ import annotations

import gzip
import math
import shutil
import subprocess
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from foamlib import FoamFile

from foam_bridge._config import STEP_HEIGHT_H, FoamEnvConfig
from foam_bridge._errors import CaseError
from foam_bridge._openfoam import OpenFOAM

__all__ = ["KINEMATIC_VISCOSITY", "TEMPLATE_DIR", "TURBULENCE_INTENSITY", "TUTORIAL_CELLS",
           "VISCOSITY_RATIO", "cell_count", "copy_case", "inlet_turbulence", "mesh_builtin",
           "mesh_parameters", "patch_names", "run_application"]

TEMPLATE_DIR = Path(__file__).parent / "cases" / "backward_facing_step"
TURBULENCE_INTENSITY = 6.1e-4
VISCOSITY_RATIO = 0.009
KINEMATIC_VISCOSITY = 1.56e-5
#: The tutorial's cell counts per block direction (20,540 cells in all).
TUTORIAL_CELLS: Mapping[str, int] = {
    "nxStartup": 2, "nxChannel": 88, "nxStep": 97, "nxDown": 33, "nyStep": 48, "nyChannel": 65,
}
#: Directories of a user's case that are results, not inputs: never copied.
_NOT_COPIED = ("processor*", "log.*", "postProcessing", "dynamicCode", "VTK")


def inlet_turbulence(velocity: float, intensity: float = TURBULENCE_INTENSITY,
                     viscosity_ratio: float = VISCOSITY_RATIO,
                     nu: float = KINEMATIC_VISCOSITY) -> tuple[float, float]:
    """Inlet (k, omega) for a speed: k = 1.5 (I U)^2, omega = k / nu_t, nu_t = viscosity_ratio * nu."""
    k = 1.5 * (intensity * velocity) ** 2
    return k, k / (viscosity_ratio * nu)


def mesh_parameters(mesh_scale: float, step_height: float) -> dict[str, float | int]:
    """blockMesh parameters of the template (lengths in units of h = 0.0127 m).

    Every cell count is ``max(1, round(n * mesh_scale))``. A step of height s*h moves the floor behind
    the step to ``y = 1 - s`` (the inlet channel and the domain length do not change) and multiplies
    the vertical cell count of the step blocks by s, so their cells keep the tutorial's size.
    """
    ratio = step_height / STEP_HEIGHT_H
    cells = {name: max(1, round(count * mesh_scale)) for name, count in TUTORIAL_CELLS.items()}
    cells["nyStep"] = max(1, round(TUTORIAL_CELLS["nyStep"] * mesh_scale * ratio))
    return {"yFloor": 1.0 - ratio, **cells}


def mesh_builtin(cfg: FoamEnvConfig, dest: Path, openfoam: OpenFOAM, step_height: float) -> None:
    """The built-in template in ``dest`` meshed for ``step_height`` (blockMesh only, 0.2-0.3 s): another
    height of a step-height family. What build_base_case read from the template (CaseInfo) does not
    depend on the height, so the env keeps the first one's instead of reading it again (~0.4 s)."""
    copy_case(TEMPLATE_DIR, dest)
    with FoamFile(dest / "system" / "meshParameters") as params:
        params.update(mesh_parameters(cfg.mesh_scale, step_height))
    run_application(openfoam, "blockMesh", dest)


def copy_case(source: Path, dest: Path, mesh: bool = True, start_time: float = 0) -> None:
    """``source`` -> ``dest`` without results (time directories but 0 and ``start_time``'s, the one a
    run starts from; logs, processor*; the mesh too unless ``mesh``), with the dictionaries of 0/ and
    system/ uncompressed (the bridge appends to some of them)."""
    if dest.exists():
        shutil.rmtree(dest)
    patterns = shutil.ignore_patterns(*_NOT_COPIED, *(() if mesh else ("polyMesh",)))

    def ignore(directory: str, names: list[str]) -> set[str]:
        skipped = set(patterns(directory, names))
        if Path(directory) == source:  # results of earlier runs: every time directory but 0 and the start
            skipped |= {name for name in names if name != "0" and _is_number(name)
                        and float(name) != start_time}
        return skipped

    shutil.copytree(source, dest, symlinks=False, ignore=ignore)
    for directory in (dest / "0", dest / "system"):
        for packed in directory.glob("*.gz") if directory.is_dir() else []:
            packed.with_suffix("").write_bytes(gzip.decompress(packed.read_bytes()))
            packed.unlink()


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def run_application(openfoam: OpenFOAM, application: str, case: Path, *args: str) -> None:
    """Run an OpenFOAM utility in ``case`` with ``args`` (log in ``log.<application>``); CaseError on
    failure."""
    log = case / f"log.{application}"
    with open(log, "wb") as out:
        result = subprocess.run([openfoam.executable(application), "-case", str(case), *args], cwd=case,
                                env=openfoam.environment(case), stdout=out, stderr=subprocess.STDOUT,
                                check=False)
    if result.returncode != 0:
        tail = log.read_text(errors="replace").strip().splitlines()[-5:]
        raise CaseError(f"{application} failed in {case} (exit {result.returncode}): {' | '.join(tail)}")


def patch_names(case: Path) -> list[str]:
    """Names of the mesh's boundary patches (constant/polyMesh/boundary)."""
    boundary = FoamFile(case / "constant" / "polyMesh" / "boundary")
    entries = boundary[None]
    return [name for name, _ in entries] if entries else []


def cell_count(case: Path) -> int:
    """Number of cells of the case's mesh: the header note of constant/polyMesh/owner (``owner.gz``
    too), which OpenFOAM's mesh writers leave; a shipped mesh without it (airFoil2D's) is counted from
    the owner list itself (the largest cell label + 1, ~0.3 s for 40k faces)."""
    owner = case / "constant" / "polyMesh" / "owner"
    owner = owner if owner.is_file() else owner.with_name("owner.gz")
    file = FoamFile(owner)
    note = file["FoamFile"].get("note")
    if note is None:
        return int(np.max(file[None])) + 1
    fields = dict(item.split(":") for item in str(note).strip('"').split())
    return int(fields["nCells"])
