"""The base case of an env, built once: the template or a user's case copied, meshed, checked and read.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

:func:`build_base_case` copies the template (or the user's case) to ``base/``, writes the mesh
parameters and runs blockMesh when there is no mesh yet, checks that the env can drive the case
(one-line :class:`foam_bridge._errors.CaseError` naming the file and entry if not), reads what it needs
from it (:class:`foam_bridge._episode_case.CaseInfo`) and, for a user's case, runs one SIMPLE iteration
of it (:func:`dry_run`: a case that cannot run fails here with OpenFOAM's message, not in every
episode). Every episode then starts from ``base/`` (foam_bridge._episode_case). A user's case is only
ever read (through ``foamDictionary -expand``) and copied, never modified.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from foamlib import FoamFile

from foam_bridge import foamdict
from foam_bridge._config import FoamEnvConfig
from foam_bridge._episode_case import (
    BRIDGE_DIR,
    CaseInfo,
    relaxation_text,
    touched_turbulence_fields,
    write_control,
    write_fixed_fv_solution,
)
from foam_bridge._errors import CaseError
from foam_bridge._fields import time_directory
from foam_bridge._logparse import LogParser
from foam_bridge._openfoam import OpenFOAM
from foam_bridge._template import TEMPLATE_DIR, copy_case, mesh_parameters, patch_names, run_application

__all__ = ["build_base_case", "check_case", "check_case_files", "check_inlet_settable", "declared_patches",
           "dry_run", "own_factors"]


def build_base_case(cfg: FoamEnvConfig, dest: Path, openfoam: OpenFOAM) -> CaseInfo:
    """Copy the template (or ``cfg.case_dir``) to ``dest``, mesh it if needed, check it, read it.

    A user's case must also run one SIMPLE iteration with its own settings (:func:`dry_run`). The
    built-in template is ours, fixed and run by every env test of the suite: it skips the dry run, so
    the paper's runs start as before.
    """
    source = TEMPLATE_DIR if cfg.case_dir is None else Path(cfg.case_dir)
    check_case_files(source, cfg, need_mesh=False)
    copy_case(source, dest, start_time=cfg.start_time)
    _drop_time_index(dest, cfg.start_time)
    if cfg.case_dir is None:
        with FoamFile(dest / "system" / "meshParameters") as params:
            params.update(mesh_parameters(cfg.mesh_scale, cfg.fixed_height))
    with _named_after(dest, source):
        info = _inspect_case(dest, cfg, openfoam)  # before blockMesh: a broken dictionary is named first
        if not (dest / "constant" / "polyMesh" / "boundary").is_file():
            run_application(openfoam, "blockMesh", dest)
        check_case_files(dest, cfg, need_mesh=True)
    if cfg.inlet_patch is not None and cfg.inlet_patch not in patch_names(dest):
        raise CaseError(f"case {source}: no patch named {cfg.inlet_patch!r} in the mesh "
                        f"(patches: {', '.join(patch_names(dest))}); name the inlet patch (inlet_patch; "
                        f"None for a case without one)")
    if cfg.case_dir is None:
        return info
    factors = info.own_factors or (cfg.action_low[0], cfg.action_low[1])
    return dataclasses.replace(info, solved_fields=dry_run(dest, cfg, openfoam, source, factors, info))


def dry_run(base: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM, source: Path, factors: tuple[float, float],
            info: CaseInfo) -> tuple[str, ...]:
    """Run one SIMPLE iteration of the meshed case ``base`` as an episode runs it, with the (alpha_u,
    alpha_p) ``factors`` (the case's own where it has them; with the alpha_t action, the case's own
    turbulence factors), in a temporary copy; returns the fields it
    solved. Everything else is the case's own: solvers, schemes, function objects, inlet.

    A case that cannot run with its own settings (an unknown solver name, a missing ``;`` that
    foamDictionary reads past, a field that blows up at once) would otherwise fail every episode at
    iteration 1, and a run of them looks like one that converges in one iteration. One-line CaseError
    with OpenFOAM's own message, naming the user's files in ``source``. Bounded by
    ``cfg.step_timeout_s``: one iteration is less than a step's ``interval``.
    """
    with tempfile.TemporaryDirectory(prefix="foam_bridge_dry_run_") as scratch:
        copy = Path(scratch) / "case"
        shutil.copytree(base, copy, ignore=shutil.ignore_patterns("polyMesh", "log.*"))
        (copy / "constant" / "polyMesh").symlink_to((base / "constant" / "polyMesh").resolve())
        (copy / "system" / BRIDGE_DIR).mkdir()
        write_control(copy, cfg, pause=False, functions=False, end=1)
        text = relaxation_text(cfg, factors[0], factors[1], info.flat_relaxation)
        write_fixed_fv_solution(copy, base, cfg, text)
        returncode, output = _run_one_iteration(copy, cfg, openfoam, source)
        parser = LogParser("", "", cfg.divergence_threshold)
        parser.feed(output)
        parser.finish()
        cause = foamdict.fatal_message(output) or parser.error or parser.diverged
        if cause or returncode != 0 or parser.completed < 1:
            tail = " | ".join(output.strip().splitlines()[-3:])
            detail = (cause or f"exit {returncode}: {tail}").replace(str(copy), str(source))
            raise CaseError(f"case {source}: simpleFoam cannot run one SIMPLE iteration with the case's own "
                            f"settings: {detail}")
    return tuple(parser.history[0])


def _run_one_iteration(copy: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM, source: Path) -> tuple[int, str]:
    """simpleFoam's exit status and output (stdout and stderr) of the dry run in ``copy``; CaseError if
    it hangs."""
    try:
        result = subprocess.run([openfoam.executable("simpleFoam"), "-case", str(copy)], cwd=copy,
                                env=openfoam.environment(copy), stdin=subprocess.DEVNULL,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                errors="replace", timeout=cfg.step_timeout_s, check=False)
    except subprocess.TimeoutExpired:  # subprocess.run killed it
        raise CaseError(f"case {source}: simpleFoam did not complete one SIMPLE iteration within "
                        f"{cfg.step_timeout_s:g} s (step_timeout_s)") from None
    return result.returncode, result.stdout


@contextlib.contextmanager
def _named_after(copy: Path, source: Path) -> Iterator[None]:
    """CaseErrors raised about files of ``copy`` name the user's own files in ``source`` instead."""
    try:
        yield
    except CaseError as err:
        raise CaseError(str(err).replace(str(copy), str(source))) from None


def check_case(source: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM, scratch: Path) -> CaseInfo:
    """Every check an env makes at creation (mesh and dry run included) on a copy of ``source`` in
    ``scratch`` (the user's case is never touched: expanding a #codeStream writes into the case).
    One-line CaseError on the first problem."""
    return build_base_case(dataclasses.replace(cfg, case_dir=source), scratch / "checked", openfoam)


def _drop_time_index(case: Path, start_time: int) -> None:
    """Remove ``uniform/time`` from the start time directory of ``case`` (FoamEnvConfig.start_time: the
    time index then counts from 0 there)."""
    start = time_directory(case, start_time) if start_time else None
    if start is not None:
        (start / "uniform" / "time").unlink(missing_ok=True)


def check_case_files(case: Path, cfg: FoamEnvConfig, need_mesh: bool) -> None:
    """One-line CaseError for the first missing file the env needs in ``case``."""
    if not case.is_dir():
        raise CaseError(f"case directory {case} does not exist")
    start = time_directory(case, cfg.start_time) if cfg.start_time else None
    if cfg.start_time and start is None:
        raise CaseError(f"case {case}: no time directory {cfg.start_time:g} to start from")
    for name in (cfg.velocity_field, cfg.pressure_field) if start is not None else ():
        if not _exists(start / name):
            raise CaseError(f"case {case}: missing {start.name}/{name} (the time it starts from)")
    needed = ["system/controlDict", "system/fvSolution", "system/fvSchemes",
              f"0/{cfg.velocity_field}", f"0/{cfg.pressure_field}",
              *(f"0/{name}" for name in touched_turbulence_fields(cfg))]
    has_mesh = (case / "constant" / "polyMesh" / "boundary").is_file()
    if need_mesh or not _exists(case / "system" / "blockMeshDict"):
        needed.append("constant/polyMesh/boundary")
    elif not has_mesh:
        needed.append("system/blockMeshDict")
    for relative in needed:
        if not _exists(case / relative):
            raise CaseError(f"case {case}: missing {relative} (a simpleFoam case needs system/, 0/ "
                            f"and a mesh or system/blockMeshDict)")


def _exists(path: Path) -> bool:
    return path.is_file() or Path(f"{path}.gz").is_file()


def _inspect_case(case: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM) -> CaseInfo:
    """Read (through ``foamDictionary -expand``) and check what the env needs from ``case``."""
    control = foamdict.expand(openfoam, case, "system/controlDict")
    functions = control.get("functions", {})
    if not isinstance(functions, dict):
        raise CaseError(f"{case / 'system/controlDict'}: entry 'functions' must be a dictionary "
                        f"(the bridge adds its function objects to it)")
    solution = foamdict.expand(openfoam, case, "system/fvSolution")
    if not isinstance(solution.get("SIMPLE"), dict):
        raise CaseError(f"{case / 'system/fvSolution'}: no SIMPLE dictionary (simpleFoam needs one)")
    relaxation = solution.get("relaxationFactors", {})
    flat = isinstance(relaxation, dict) and bool(relaxation) and not (
        "fields" in relaxation or "equations" in relaxation)
    foamdict.expand(openfoam, case, "system/fvSchemes")
    meshed = (case / "constant" / "polyMesh" / "boundary").is_file()
    if not meshed and _exists(case / "system" / "blockMeshDict"):
        foamdict.expand(openfoam, case, "system/blockMeshDict", parse=False)  # a one-line error first
    foamdict.expand(openfoam, case, f"0/{cfg.pressure_field}")
    velocity = foamdict.expand(openfoam, case, f"0/{cfg.velocity_field}")
    changes_inlet = cfg.velocity_range is not None
    inlet = {} if cfg.inlet_patch is None else _inlet_entry(case, cfg, velocity, f"0/{cfg.velocity_field}",
                                                            changes_inlet)
    speed, direction, inlet_state = _inlet_velocity(inlet)
    if changes_inlet:
        _check_turbulence_inlets(case, cfg, openfoam)
    nu = None if cfg.turbulence_formula is None else _viscosity(case, openfoam)
    start = time_directory(case, cfg.start_time) if cfg.start_time else None
    if start is not None:  # the run starts from these fields
        velocity = foamdict.expand(openfoam, case, f"{start.name}/{cfg.velocity_field}")
    cells_state = _mean_magnitude_squared(velocity.get("internalField", 0.0))
    return CaseInfo(speed, direction, inlet_state, cells_state, flat, nu,
                    own_factors=own_factors(relaxation, cfg))


def declared_patches(case: Path, openfoam: OpenFOAM) -> list[str] | None:
    """The boundary patches of ``case`` before anything is built: its mesh's, else its blockMeshDict's;
    None when neither says (a mesh another tool makes)."""
    if (case / "constant" / "polyMesh" / "boundary").is_file():
        return patch_names(case)
    if not _exists(case / "system" / "blockMeshDict"):
        return None
    boundary = foamdict.expand(openfoam, case, "system/blockMeshDict").get("boundary", [])
    return [entry[0] for entry in boundary if isinstance(entry, list | tuple) and entry]


def own_factors(relaxation: Any, cfg: FoamEnvConfig) -> tuple[float, float] | None:
    """The case's own (alpha_u, alpha_p) from its expanded relaxationFactors: U's equation factor and p's
    field factor (the old flat layout: both at the top); None if either is missing."""
    if not isinstance(relaxation, dict):
        return None
    flat = "fields" not in relaxation and "equations" not in relaxation
    equations = relaxation if flat else relaxation.get("equations", {})
    fields = relaxation if flat else relaxation.get("fields", {})
    try:
        factors = (float(foamdict.lookup(equations, cfg.velocity_field)),
                   float(foamdict.lookup(fields, cfg.pressure_field)))
    except (KeyError, TypeError, ValueError):
        return None
    return factors if all(0 < f <= 1 for f in factors) else None


def check_inlet_settable(case: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM) -> None:
    """One-line CaseError unless the bridge can set the inlet speed of ``case`` (a fixedValue inlet in
    an ascii 0/U, and fixedValue inlet k/omega where a turbulence formula applies)."""
    velocity = foamdict.expand(openfoam, case, f"0/{cfg.velocity_field}")
    _inlet_entry(case, cfg, velocity, f"0/{cfg.velocity_field}", True)
    _check_turbulence_inlets(case, cfg, openfoam)


def _check_turbulence_inlets(case: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM) -> None:
    """The inlet k/omega the turbulence formula sets must be fixedValue entries of ascii files."""
    if cfg.turbulence_formula is None:
        return
    for name in (n for n in ("k", "omega") if n in cfg.turbulence_fields):
        _inlet_entry(case, cfg, foamdict.expand(openfoam, case, f"0/{name}"), f"0/{name}", True)


def _inlet_entry(case: Path, cfg: FoamEnvConfig, field: dict[str, Any], relative: str,
                 must_be_fixed: bool) -> dict[str, Any]:
    """The inlet's boundary entry of an expanded field file; CaseError if the bridge cannot set it."""
    try:
        entry = foamdict.lookup(field, f"boundaryField/{cfg.inlet_patch}")
    except KeyError:
        raise CaseError(f"{case / relative}: no boundaryField entry for the inlet patch "
                        f"{cfg.inlet_patch!r} (name the inlet patch: inlet_patch; None for a case "
                        f"without one)") from None
    if not isinstance(entry, dict):
        raise CaseError(f"{case / relative}: boundaryField/{cfg.inlet_patch} is not a dictionary")
    if must_be_fixed:
        if entry.get("type") != "fixedValue":
            raise CaseError(f"{case / relative}: boundaryField/{cfg.inlet_patch} is type "
                            f"{entry.get('type')!r}; setting the inlet needs a fixedValue inlet "
                            f"(or keep the case's own: inlet_velocity=None)")
        header = field.get("FoamFile", {})
        if isinstance(header, dict) and header.get("format", "ascii") != "ascii":
            raise CaseError(f"{case / relative}: format {header.get('format')}; setting the inlet needs "
                            f"an ascii field file")
    return entry


def _inlet_velocity(entry: dict[str, Any]) -> tuple[float | None, tuple[float, float, float], float]:
    """(|mean inlet U| or None, its direction (x if none), mean |U|^2 over the inlet)."""
    value = entry.get("value")
    if value is None or isinstance(value, str):
        return None, (1.0, 0.0, 0.0), 0.0
    array = np.asarray(value, dtype=float).reshape(-1, 3)
    mean = array.mean(axis=0)
    norm = float(np.linalg.norm(mean))
    direction = tuple(float(c) for c in (mean / norm if norm > 0 else np.array([1.0, 0.0, 0.0])))
    return norm, direction, _mean_magnitude_squared(value)  # type: ignore[return-value]


def _viscosity(case: Path, openfoam: OpenFOAM) -> float:
    """The case's kinematic viscosity ``nu`` (constant/transportProperties)."""
    relative = "constant/transportProperties"
    value = foamdict.expand(openfoam, case, relative).get("nu")
    value = getattr(value, "value", value)
    if isinstance(value, list | tuple):
        value = value[-1]
    try:
        nu = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise CaseError(f"{case / relative}: no scalar entry 'nu' (the inlet turbulence formula needs the "
                        f"kinematic viscosity)") from None
    if not (math.isfinite(nu) and nu > 0):
        raise CaseError(f"{case / relative}: nu = {nu!r}; expected a positive viscosity")
    return nu


def _mean_magnitude_squared(value: Any) -> float:
    if isinstance(value, str):
        return 0.0
    array = np.asarray(value, dtype=float)
    if array.ndim <= 1:
        return float(np.sum(array**2))
    return float(np.mean(np.sum(array**2, axis=-1)))
