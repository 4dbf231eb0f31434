"""Case generation: the built-in backward-facing step template or a user's simpleFoam case.

Two stages:

1. :func:`build_base_case` (once per env): copy the template (or the user's case) to ``base/``, write
   the mesh parameters and run blockMesh when there is no mesh yet, and check that every file, field
   and the inlet patch the env needs exist (one-line :class:`foam_bridge.errors.CaseError` if not).
2. :func:`write_episode_case` (every episode): copy ``base/`` to a fresh directory (the mesh is
   symlinked), set the inlet velocity (and inlet k, omega), and install the bridge's machinery:

   - controlDict: ``endTime = max_iterations``, binary writes only at the end, runTimeModifiable with
     ``OptimisationSwitches { fileModificationSkew 0; fileModificationChecking timeStamp; }`` and the
     bridge's function objects instead of the case's own: ``magSqr(U)``, its ``volFieldValue``
     average over all cells and ``surfaceFieldValue`` average over the inlet faces (printed every
     iteration: the paper's state), and the pause (see below).
   - fvSolution: ``SIMPLE.consistent`` from the variant, ``SIMPLE.residualControl`` = the convergence
     criterion (simpleFoam stops itself on the iteration it is met), the case's relaxationFactors
     moved out, ``#include "foamBridgeRelaxation"`` appended. ``foamBridgeRelaxation`` is a FIFO.

The pause: a ``timeActivatedFileUpdate`` function object replaces ``system/fvSolution`` by an identical
copy after iterations interval, 2 interval, ... OpenFOAM v1912 executes function objects *before* it
re-reads modified files in ``Time::run()``, so simpleFoam re-reads fvSolution right after iteration K,
opens the FIFO and blocks until the bridge writes the new relaxationFactors into it: the solver stops
exactly between iterations K and K+1 and the new factors govern iteration K+1 onwards (measured, and
tested in tests/test_foam_env.py). The very first read (at start-up) takes the episode's first action.
(Why not a ``systemCall`` function object blocking on a FIFO: v1912 refuses system calls when run as
root, which containers and CI usually are; and the factors would still have to travel by a file.)

Inlet turbulence (the paper's values: intensity I = 6.1e-4, nu_t/nu = 0.009, nu = 1.56e-5 m^2/s):
``k = 1.5 (I U)^2`` and ``omega = k / nu_t`` with ``nu_t = 0.009 nu``. (The tutorial's omega, 181728,
does not follow this formula; we follow the paper.)
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from foamlib import FoamFile

from foam_bridge.config import STEP_HEIGHT_H, FoamEnvConfig
from foam_bridge.errors import CaseError
from foam_bridge.openfoam import OpenFOAM

TEMPLATE_DIR = Path(__file__).parent / "cases" / "backward_facing_step"
TURBULENCE_INTENSITY = 6.1e-4
VISCOSITY_RATIO = 0.009
KINEMATIC_VISCOSITY = 1.56e-5
#: The tutorial's cell counts per block direction (20,540 cells in all).
TUTORIAL_CELLS: Mapping[str, int] = {
    "nxStartup": 2, "nxChannel": 88, "nxStep": 97, "nxDown": 33, "nyStep": 48, "nyChannel": 65,
}
RELAXATION_FIFO = "foamBridgeRelaxation"
FVSOLUTION_COPY = "fvSolution.foamBridge"
STATE_FIELD = "foamBridgeMagSqrU"
CELLS_FUNCTION = "foamBridgeCells"
INLET_FUNCTION = "foamBridgeInlet"
PAUSE_FUNCTION = "foamBridgePause"
_FIELD_LIBS = ["libfieldFunctionObjects.so"]


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


def build_base_case(cfg: FoamEnvConfig, dest: Path, openfoam: OpenFOAM) -> None:
    """Copy the template (or ``cfg.case_dir``) to ``dest``, mesh it if needed, and check it."""
    source = TEMPLATE_DIR if cfg.case_dir is None else Path(cfg.case_dir)
    check_case_files(source, cfg, need_mesh=False)
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(source, dest, symlinks=False, ignore=shutil.ignore_patterns("processor*", "log.*"))
    _remove_time_directories(dest)
    if cfg.case_dir is None:
        with FoamFile(dest / "system" / "meshParameters") as params:
            params.update(mesh_parameters(cfg.mesh_scale, cfg.step_height))
    if not (dest / "constant" / "polyMesh" / "boundary").is_file():
        run_application(openfoam, "blockMesh", dest)
    check_case_files(dest, cfg, need_mesh=True)
    if cfg.inlet_patch not in patch_names(dest):
        raise CaseError(f"case {source}: no patch named {cfg.inlet_patch!r} in the mesh "
                        f"(patches: {', '.join(patch_names(dest))}); set FoamEnvConfig.inlet_patch")


def check_case_files(case: Path, cfg: FoamEnvConfig, need_mesh: bool) -> None:
    """One-line CaseError for the first missing file the env needs in ``case``."""
    if not case.is_dir():
        raise CaseError(f"case directory {case} does not exist")
    needed = ["system/controlDict", "system/fvSolution", "system/fvSchemes",
              f"0/{cfg.velocity_field}", f"0/{cfg.pressure_field}",
              *(f"0/{name}" for name in cfg.turbulence_fields)]
    has_mesh = (case / "constant" / "polyMesh" / "boundary").is_file()
    if need_mesh or not (case / "system" / "blockMeshDict").is_file():
        needed.append("constant/polyMesh/boundary")
    elif not has_mesh:
        needed.append("system/blockMeshDict")
    for relative in needed:
        if not (case / relative).is_file():
            raise CaseError(f"case {case}: missing {relative} (a simpleFoam case needs system/, 0/ "
                            f"and a mesh or system/blockMeshDict)")


def run_application(openfoam: OpenFOAM, application: str, case: Path) -> None:
    """Run an OpenFOAM utility in ``case`` (log in ``log.<application>``); CaseError on failure."""
    log = case / f"log.{application}"
    with open(log, "wb") as out:
        result = subprocess.run([openfoam.executable(application), "-case", str(case)], cwd=case,
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
    """Number of cells of the case's mesh (from the header note of constant/polyMesh/owner)."""
    note = str(FoamFile(case / "constant" / "polyMesh" / "owner")["FoamFile"]["note"])
    fields = dict(item.split(":") for item in note.strip('"').split())
    return int(fields["nCells"])


def write_episode_case(base: Path, dest: Path, cfg: FoamEnvConfig, inlet_velocity: float) -> None:
    """Fresh episode case in ``dest`` from the meshed ``base``: inlet values, controlDict, fvSolution."""
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(base, dest, ignore=shutil.ignore_patterns("polyMesh", "log.*"))
    (dest / "constant" / "polyMesh").symlink_to((base / "constant" / "polyMesh").resolve())
    _set_inlet(dest, cfg, inlet_velocity)
    _write_control_dict(dest, cfg)
    _write_fv_solution(dest, cfg)
    os.mkfifo(dest / "system" / RELAXATION_FIFO)


def make_uninterrupted(case: Path, cfg: FoamEnvConfig, alpha_u: float, alpha_p: float) -> None:
    """Turn an episode case into a plain one: constant factors in a regular file, no pause.

    The factors are written as the bridge would feed them (:func:`relaxation_text` on the case's own
    factors). The reference run for "chunked == uninterrupted" and for the overhead benchmark.
    """
    fifo = case / "system" / RELAXATION_FIFO
    fifo.unlink()
    fifo.write_bytes(relaxation_text(case_relaxation(case), cfg, alpha_u, alpha_p))
    with FoamFile(case / "system" / "controlDict") as control:
        del control["functions"][PAUSE_FUNCTION]


def relaxation_text(base: Mapping[str, Any], cfg: FoamEnvConfig, alpha_u: float, alpha_p: float) -> bytes:
    """The relaxationFactors entry the bridge feeds through the FIFO for one action.

    ``base``: the case's own factors (:func:`case_relaxation`); they stay in force for every other
    field. alpha_u relaxes the velocity equation and (unless ``relax_k_omega`` is set) the turbulence
    equations, alpha_p the pressure field.
    """
    fields = dict(base.get("fields", {}))
    equations = dict(base.get("equations", {}))
    fields[cfg.pressure_field] = float(alpha_p)
    equations[cfg.velocity_field] = float(alpha_u)
    turbulence = float(alpha_u) if cfg.relax_k_omega is None else float(cfg.relax_k_omega)
    for name in cfg.turbulence_fields:
        equations[name] = turbulence
    return FoamFile.dumps({"relaxationFactors": {"fields": fields, "equations": equations}},
                          ensure_header=False) + b"\n"


def initial_state(case: Path, cfg: FoamEnvConfig) -> tuple[float, float]:
    """(mean |U|^2 over the inlet faces, mean |U|^2 over the cells) of the case's 0/U.

    Arithmetic means, as the solver-side function objects compute them later. A uniform internal
    field counts as uniform over all cells; an inlet without a ``value`` entry contributes 0.
    """
    velocity = FoamFile(case / "0" / cfg.velocity_field)
    cells = _mean_magnitude_squared(velocity["internalField"])
    inlet_entry = velocity["boundaryField"].get(cfg.inlet_patch)
    inlet = 0.0
    if inlet_entry is not None and "value" in inlet_entry:
        inlet = _mean_magnitude_squared(inlet_entry["value"])
    return inlet, cells


def _mean_magnitude_squared(value: Any) -> float:
    array = np.asarray(value, dtype=float)
    if array.ndim <= 1:
        return float(np.sum(array**2))
    return float(np.mean(np.sum(array**2, axis=-1)))


def _remove_time_directories(case: Path) -> None:
    """Drop every time directory but 0 (a user's case may hold results)."""
    for child in case.iterdir():
        if child.is_dir() and child.name != "0" and _is_number(child.name):
            shutil.rmtree(child)


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def _set_inlet(case: Path, cfg: FoamEnvConfig, speed: float) -> None:
    """Inlet U = speed along the inlet's current direction (x if none); inlet k/omega from the speed."""
    with FoamFile(case / "0" / cfg.velocity_field) as velocity:
        entry = velocity["boundaryField"].get(cfg.inlet_patch)
        if entry is None or "value" not in entry:
            raise CaseError(f"0/{cfg.velocity_field}: the inlet patch {cfg.inlet_patch!r} needs an explicit "
                            f"boundaryField entry with a value (e.g. fixedValue)")
        current = np.asarray(entry["value"], dtype=float).reshape(-1, 3).mean(axis=0)
        norm = float(np.linalg.norm(current))
        direction = current / norm if norm > 0 else np.array([1.0, 0.0, 0.0])
        entry["value"] = speed * direction
    k, omega = inlet_turbulence(speed)
    for name, value in (("k", k), ("omega", omega)):
        if name not in cfg.turbulence_fields:
            continue
        with FoamFile(case / "0" / name) as field:
            inlet = field["boundaryField"].get(cfg.inlet_patch)
            if inlet is not None and inlet.get("type") == "fixedValue":
                inlet["value"] = value
            if cfg.case_dir is None:
                field["internalField"] = value


def _write_control_dict(case: Path, cfg: FoamEnvConfig) -> None:
    with FoamFile(case / "system" / "controlDict") as control:
        control.update({
            "application": "simpleFoam", "startFrom": "startTime", "startTime": 0, "stopAt": "endTime",
            "endTime": cfg.max_iterations, "deltaT": 1, "writeControl": "timeStep",
            "writeInterval": cfg.max_iterations, "purgeWrite": 0, "writeFormat": "binary",
            "writePrecision": 17, "runTimeModifiable": True,
            "OptimisationSwitches": {"fileModificationSkew": 0, "fileModificationChecking": "timeStamp"},
        })
        if "functions" in control:
            del control["functions"]
        control["functions"] = _function_objects(cfg)


def _function_objects(cfg: FoamEnvConfig) -> dict[str, Any]:
    """The paper's state printed every iteration, then the pause after every ``interval`` iterations."""
    every_iteration = {"executeControl": "timeStep", "executeInterval": 1, "writeControl": "timeStep",
                       "writeInterval": 1, "log": True, "writeToFile": False, "writeFields": False}
    copy = f'"$FOAM_CASE/system/{FVSOLUTION_COPY}"'
    pauses = [[k, copy] for k in range(cfg.interval, cfg.max_iterations, cfg.interval)]
    return {
        "foamBridgeMagSqrU": {"type": "magSqr", "libs": _FIELD_LIBS, "field": cfg.velocity_field,
                              "result": STATE_FIELD, "executeControl": "timeStep", "executeInterval": 1,
                              "writeControl": "none"},
        CELLS_FUNCTION: {"type": "volFieldValue", "libs": _FIELD_LIBS, "fields": [STATE_FIELD],
                         "operation": "average", "regionType": "all", **every_iteration},
        INLET_FUNCTION: {"type": "surfaceFieldValue", "libs": _FIELD_LIBS, "fields": [STATE_FIELD],
                         "operation": "average", "regionType": "patch", "name": cfg.inlet_patch,
                         "surfaceFormat": "none", **every_iteration},
        PAUSE_FUNCTION: {"type": "timeActivatedFileUpdate", "libs": ["libutilityFunctionObjects.so"],
                         "executeControl": "timeStep", "executeInterval": 1, "writeControl": "none",
                         "fileToUpdate": '"$FOAM_CASE/system/fvSolution"',
                         "timeVsFile": pauses or [[cfg.max_iterations + 1, copy]]},
    }


def _write_fv_solution(case: Path, cfg: FoamEnvConfig) -> None:
    """SIMPLE settings from cfg; the relaxation factors move to the FIFO (the case's own are kept)."""
    path = case / "system" / "fvSolution"
    with FoamFile(path) as solution:
        base = solution["relaxationFactors"].as_dict() if "relaxationFactors" in solution else {}
        if "relaxationFactors" in solution:
            del solution["relaxationFactors"]
        solution["SIMPLE"]["consistent"] = cfg.simple_variant == "SIMPLEC"
        if "residualControl" in solution["SIMPLE"]:
            del solution["SIMPLE"]["residualControl"]
        solution["SIMPLE"]["residualControl"] = {name: float(v) for name, v in cfg.convergence.items()}
    (case / "system" / "relaxationFactors.orig").write_bytes(
        FoamFile.dumps({"relaxationFactors": _normalise_relaxation(base)}, ensure_header=False))
    with open(path, "a") as out:
        out.write(f'\n#include "{RELAXATION_FIFO}"\n')
    shutil.copyfile(path, case / "system" / FVSOLUTION_COPY)


def _normalise_relaxation(base: Mapping[str, Any]) -> dict[str, dict[str, Any]]:
    """Old-style flat relaxationFactors (``U 0.7; p 0.3;``) become fields (p) and equations (rest)."""
    if "fields" in base or "equations" in base:
        return {"fields": dict(base.get("fields", {})), "equations": dict(base.get("equations", {}))}
    fields = {k: v for k, v in base.items() if k == "p"}
    return {"fields": fields, "equations": {k: v for k, v in base.items() if k != "p"}}


def case_relaxation(case: Path) -> dict[str, dict[str, Any]]:
    """The case's own relaxationFactors (moved out of fvSolution by write_episode_case)."""
    return FoamFile(case / "system" / "relaxationFactors.orig")["relaxationFactors"].as_dict()
