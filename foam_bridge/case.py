"""Case generation: the built-in backward-facing step template or a user's simpleFoam case.

Two stages:

1. :func:`build_base_case` (once per env): copy the template (or the user's case) to ``base/``, write
   the mesh parameters and run blockMesh when there is no mesh yet, check that the env can drive the
   case (one-line :class:`foam_bridge.errors.CaseError` naming the file and entry if not), read what
   it needs from it (:class:`CaseInfo`) and, for a user's case, run one SIMPLE iteration of it
   (:func:`dry_run`: a case that cannot run fails here with OpenFOAM's message, not in every episode).
2. :func:`write_episode_case` (every episode): copy ``base/`` to a fresh directory (the mesh is
   symlinked) and install the bridge's machinery.

A user's dictionaries are never re-serialised: the bridge *appends* one ``#include`` of a file it
writes itself to the end of controlDict and fvSolution (OpenFOAM merges a later entry into an earlier
one of the same name), so ``#include``/``#includeFunc``/``$var``/regex keys, comments and everything the
bridge does not set stay exactly the user's. What it sets (``system/foamBridge/``):

- controlDict: ``startTime 0``, ``endTime = max_iterations``, ``deltaT 1``, one write at the end,
  ``runTimeModifiable`` with ``OptimisationSwitches { fileModificationSkew 0; fileModificationChecking
  timeStamp; }``, and its function objects *beside* the case's own (merged into ``functions``):
  ``magSqr(U)``, its ``volFieldValue`` average over all cells and ``surfaceFieldValue`` average over the
  inlet faces (printed every iteration: the paper's state), and the pause (see below).
- fvSolution: ``SIMPLE`` is the case's own with ``residualControl`` replaced by the convergence
  criterion (simpleFoam stops itself on the iteration it is met) and ``consistent`` set only if a
  SIMPLE variant applies (the built-in case's SIMPLEC, or the user's explicit choice); then the
  relaxation factors of this step, read from a FIFO and merged into the case's own
  ``relaxationFactors``: only U, p and (if a factor applies) the turbulence fields change.
- the inlet (only when its speed is set: always for the built-in case, opt-in for a user's):
  ``boundaryField { <inlet> { type fixedValue; value uniform (...); } }`` appended to 0/U (the
  direction is the case's), and the inlet k/omega likewise when a turbulence formula applies.

The pause: a ``timeActivatedFileUpdate`` function object replaces ``system/fvSolution`` after iterations
interval, 2 interval, ... by a copy whose relaxation ``#include`` names a FIFO of its own,
``foamBridge/relaxation.<K>``. OpenFOAM v1912 executes function objects *before* it re-reads modified
files in ``Time::run()``, so simpleFoam re-reads fvSolution right after iteration K, opens that FIFO
and blocks until the bridge writes the new relaxationFactors into it: the solver stops exactly
between iterations K and K+1 and the new factors govern iteration K+1 onwards (measured, and tested
in tests/test_foam_env.py). One FIFO per boundary means a reader on FIFO K *is* the pause at K: no
log line has to be trusted, and a stale reader of an earlier read can never be taken for it. The
start-up read takes the episode's first action from ``relaxation.0``. (Why not a ``systemCall``
function object blocking on a FIFO: v1912 refuses system calls when run as root, which containers and
CI usually are; and the factors would still have to travel by a file.)

Inlet turbulence of the built-in case (the paper's values: intensity I = 6.1e-4, nu_t/nu = 0.009,
nu = 1.56e-5 m^2/s from its transportProperties): ``k = 1.5 (I U)^2`` and ``omega = k / nu_t`` with
``nu_t = 0.009 nu``. (The tutorial's omega, 181728, does not follow this formula; we follow the paper.)
"""

from __future__ import annotations

import contextlib
import dataclasses
import gzip
import math
import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from foamlib import FoamFile

from foam_bridge import foamdict
from foam_bridge.config import (
    FOLLOW_ALPHA_U,
    K_OMEGA_ACTION,
    STEP_HEIGHT_H,
    FoamEnvConfig,
    without_convergence_test,
)
from foam_bridge.errors import CaseError
from foam_bridge.fields import time_directories
from foam_bridge.logparse import LogParser
from foam_bridge.openfoam import OpenFOAM

TEMPLATE_DIR = Path(__file__).parent / "cases" / "backward_facing_step"
TURBULENCE_INTENSITY = 6.1e-4
VISCOSITY_RATIO = 0.009
KINEMATIC_VISCOSITY = 1.56e-5
#: The tutorial's cell counts per block direction (20,540 cells in all).
TUTORIAL_CELLS: Mapping[str, int] = {
    "nxStartup": 2, "nxChannel": 88, "nxStep": 97, "nxDown": 33, "nyStep": 48, "nyChannel": 65,
}
#: The bridge's files live in ``system/BRIDGE_DIR`` of an episode case.
BRIDGE_DIR = "foamBridge"
CONTROL_INCLUDE = f"{BRIDGE_DIR}/controlDict"
SIMPLE_INCLUDE = f"{BRIDGE_DIR}/SIMPLE"
#: Relaxation factors read at start-up from a regular file (a restart, a confirmation check): no pause.
FIXED_RELAXATION = f"{BRIDGE_DIR}/relaxation.fixed"
STATE_FIELD = "foamBridgeMagSqrU"
CELLS_FUNCTION = "foamBridgeCells"
INLET_FUNCTION = "foamBridgeInlet"
PAUSE_FUNCTION = "foamBridgePause"
_FIELD_LIBS = ["libfieldFunctionObjects.so"]
#: Directories of a user's case that are results, not inputs: never copied.
_NOT_COPIED = ("processor*", "log.*", "postProcessing", "dynamicCode", "VTK")


def relaxation_fifo(case: Path, boundary: int) -> Path:
    """The FIFO the solver reads its relaxation factors from at the pause after iteration ``boundary``."""
    return case / "system" / BRIDGE_DIR / f"relaxation.{boundary}"


def _fv_solution_copy(case: Path, boundary: int) -> Path:
    return case / "system" / BRIDGE_DIR / f"fvSolution.{boundary}"


def pause_boundaries(cfg: FoamEnvConfig) -> list[int]:
    """Iterations after which the solver pauses (0 = start-up, then every ``interval`` before the cap)."""
    return list(range(0, cfg.max_iterations, cfg.interval))


@dataclass(frozen=True)
class CaseInfo:
    """What the env reads from a base case once (through OpenFOAM's own expansion of its files).

    ``inlet_speed``/``inlet_direction``: |mean inlet U| and its direction (None/x if the inlet has
    no value); ``inlet_state``/``cells_state``: mean |U|^2 over the inlet faces and over the cells of
    0/U; ``flat_relaxation``: the case's relaxationFactors use the old flat layout (``U 0.7;``, no
    ``fields``/``equations``); ``nu``: the kinematic viscosity (only read when a turbulence formula
    applies); ``solved_fields``: the fields whose equations its first SIMPLE iteration solved, as
    simpleFoam names them (``Ux``, ``Uy``, ``p``, ``k``, ...; from the dry run of a user's case, empty
    for the built-in one); ``own_factors``: its own (alpha_u, alpha_p), None if it lacks either.
    """

    inlet_speed: float | None
    inlet_direction: tuple[float, float, float]
    inlet_state: float
    cells_state: float
    flat_relaxation: bool = False
    nu: float | None = None
    solved_fields: tuple[str, ...] = ()
    own_factors: tuple[float, float] | None = None


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


# ----- base case ------------------------------------------------------------------------------------
def build_base_case(cfg: FoamEnvConfig, dest: Path, openfoam: OpenFOAM) -> CaseInfo:
    """Copy the template (or ``cfg.case_dir``) to ``dest``, mesh it if needed, check it, read it.

    A user's case must also run one SIMPLE iteration with its own settings (:func:`dry_run`). The
    built-in template is ours, fixed and run by every env test of the suite: it skips the dry run, so
    the paper's runs start as before.
    """
    source = TEMPLATE_DIR if cfg.case_dir is None else Path(cfg.case_dir)
    check_case_files(source, cfg, need_mesh=False)
    copy_case(source, dest)
    if cfg.case_dir is None:
        with FoamFile(dest / "system" / "meshParameters") as params:
            params.update(mesh_parameters(cfg.mesh_scale, cfg.fixed_height))
    with _named_after(dest, source):
        info = inspect_case(dest, cfg, openfoam)  # before blockMesh: a broken dictionary is named first
        if not (dest / "constant" / "polyMesh" / "boundary").is_file():
            run_application(openfoam, "blockMesh", dest)
        check_case_files(dest, cfg, need_mesh=True)
    if cfg.inlet_patch not in patch_names(dest):
        raise CaseError(f"case {source}: no patch named {cfg.inlet_patch!r} in the mesh "
                        f"(patches: {', '.join(patch_names(dest))}); set FoamEnvConfig.inlet_patch")
    if cfg.case_dir is None:
        return info
    factors = info.own_factors or (cfg.action_low[0], cfg.action_low[1])
    return dataclasses.replace(info, solved_fields=dry_run(dest, cfg, openfoam, source, factors, info))


def mesh_builtin(cfg: FoamEnvConfig, dest: Path, openfoam: OpenFOAM, step_height: float) -> None:
    """The built-in template in ``dest`` meshed for ``step_height`` (blockMesh only, 0.2-0.3 s): another
    height of a step-height family. What build_base_case read from the template (CaseInfo) does not
    depend on the height, so the env keeps the first one's instead of reading it again (~0.4 s)."""
    copy_case(TEMPLATE_DIR, dest)
    with FoamFile(dest / "system" / "meshParameters") as params:
        params.update(mesh_parameters(cfg.mesh_scale, step_height))
    run_application(openfoam, "blockMesh", dest)


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
        _write_control(copy, cfg, pause=False, functions=False, end=1)
        text = relaxation_text(cfg, factors[0], factors[1], info.flat_relaxation)
        _write_fixed_fv_solution(copy, base, cfg, text)
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


def copy_case(source: Path, dest: Path, mesh: bool = True) -> None:
    """``source`` -> ``dest`` without results (time directories but 0, logs, processor*; the mesh too
    unless ``mesh``), with the dictionaries of 0/ and system/ uncompressed (the bridge appends to some
    of them)."""
    if dest.exists():
        shutil.rmtree(dest)
    patterns = shutil.ignore_patterns(*_NOT_COPIED, *(() if mesh else ("polyMesh",)))

    def ignore(directory: str, names: list[str]) -> set[str]:
        skipped = set(patterns(directory, names))
        if Path(directory) == source:  # results of earlier runs: every time directory but 0
            skipped |= {name for name in names if name != "0" and _is_number(name)}
        return skipped

    shutil.copytree(source, dest, symlinks=False, ignore=ignore)
    for directory in (dest / "0", dest / "system"):
        for packed in directory.glob("*.gz") if directory.is_dir() else []:
            packed.with_suffix("").write_bytes(gzip.decompress(packed.read_bytes()))
            packed.unlink()


def check_case(source: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM, scratch: Path) -> CaseInfo:
    """Every check an env makes at creation (mesh and dry run included) on a copy of ``source`` in
    ``scratch`` (the user's case is never touched: expanding a #codeStream writes into the case).
    One-line CaseError on the first problem."""
    return build_base_case(dataclasses.replace(cfg, case_dir=source), scratch / "checked", openfoam)


def check_case_files(case: Path, cfg: FoamEnvConfig, need_mesh: bool) -> None:
    """One-line CaseError for the first missing file the env needs in ``case``."""
    if not case.is_dir():
        raise CaseError(f"case directory {case} does not exist")
    needed = ["system/controlDict", "system/fvSolution", "system/fvSchemes",
              f"0/{cfg.velocity_field}", f"0/{cfg.pressure_field}",
              *(f"0/{name}" for name in _touched_turbulence_fields(cfg))]
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


def _touched_turbulence_fields(cfg: FoamEnvConfig) -> list[str]:
    """Turbulence fields whose files the bridge edits (inlet k/omega from a formula)."""
    if cfg.turbulence_formula is None:
        return []
    return [name for name in ("k", "omega") if name in cfg.turbulence_fields]


def inspect_case(case: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM) -> CaseInfo:
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
    inlet = _inlet_entry(case, cfg, velocity, f"0/{cfg.velocity_field}", changes_inlet)
    speed, direction, inlet_state = _inlet_velocity(inlet)
    if changes_inlet:
        check_turbulence_inlets(case, cfg, openfoam)
    nu = None if cfg.turbulence_formula is None else _viscosity(case, openfoam)
    cells_state = _mean_magnitude_squared(velocity.get("internalField", 0.0))
    return CaseInfo(speed, direction, inlet_state, cells_state, flat, nu,
                    own_factors=own_factors(relaxation, cfg))


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
    check_turbulence_inlets(case, cfg, openfoam)


def check_turbulence_inlets(case: Path, cfg: FoamEnvConfig, openfoam: OpenFOAM) -> None:
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
                        f"{cfg.inlet_patch!r} (set FoamEnvConfig.inlet_patch)") from None
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


# ----- episode case ---------------------------------------------------------------------------------
def write_episode_case(base: Path, dest: Path, cfg: FoamEnvConfig, inlet_velocity: float | None,
                       info: CaseInfo) -> None:
    """Fresh episode case in ``dest`` from the meshed ``base``: inlet, controlDict, fvSolution, FIFOs.

    ``inlet_velocity`` None keeps the case's own inlet (a user's case without ``inlet_velocity``).
    """
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(base, dest, ignore=shutil.ignore_patterns("polyMesh", "log.*"))
    (dest / "constant" / "polyMesh").symlink_to((base / "constant" / "polyMesh").resolve())
    (dest / "system" / BRIDGE_DIR).mkdir()
    if inlet_velocity is not None:
        set_inlet = _set_builtin_inlet if cfg.case_dir is None else _set_user_inlet
        set_inlet(dest, cfg, info, inlet_velocity)
    _write_control(dest, cfg, pause=True)
    _write_fv_solution(dest, cfg)


def make_uninterrupted(case: Path, cfg: FoamEnvConfig, alpha_u: float, alpha_p: float,
                       flat: bool = False, functions: bool = True, alpha_t: float | None = None,
                       turbulence: Sequence[str] | None = None) -> None:
    """Turn an episode case into a plain one: constant factors in a regular file, no pause.

    The factors are written as the bridge would feed them (:func:`relaxation_text`; ``alpha_t`` and
    ``turbulence`` as there). The reference run for "chunked == uninterrupted" and for the overhead
    benchmark (``functions=False``: not even the bridge's state function objects).
    """
    first = relaxation_fifo(case, 0)
    first.unlink()
    first.write_bytes(relaxation_text(cfg, alpha_u, alpha_p, flat, alpha_t, turbulence))
    _write_control(case, cfg, pause=False, functions=functions)


def write_restart(case: Path, base: Path, cfg: FoamEnvConfig, time: int, text: bytes) -> None:
    """Make the episode case go on from the fields it wrote at iteration ``time`` (foam_bridge.confirm).

    simpleFoam then starts from ``latestTime`` with the factors ``text`` (read from a regular file, so
    the start-up does not pause), without a convergence test of its own (the bridge tests at the step
    boundaries), writes its fields at every boundary (the bridge's checks read them) and pauses at the
    boundaries after ``time``, as before.
    """
    _write_fixed_fv_solution(case, base, cfg, text)
    _write_control(case, cfg, pause=True, restart_at=time)


def write_check_case(case: Path, base: Path, dest: Path, cfg: FoamEnvConfig, time: int, text: bytes) -> None:
    """A copy of the episode case in ``dest`` that runs one SIMPLE iteration from the fields of ``time``
    with the factors ``text`` and no convergence test (foam_bridge.confirm); nothing is written."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    for part in ("system", "constant"):
        shutil.copytree(case / part, dest / part, symlinks=True,
                        ignore=lambda directory, names: {n for n in names if n.startswith(("relaxation.",
                                                                                             "fvSolution."))})
    (written,) = [path for value, path in time_directories(case) if value == time] or [case / str(time)]
    shutil.copytree(written, dest / written.name)
    _write_fixed_fv_solution(dest, base, cfg, text)
    _write_control(dest, cfg, pause=False, functions=False, restart_at=time, end=time + 1)


def _write_fixed_fv_solution(case: Path, base: Path, cfg: FoamEnvConfig, text: bytes) -> None:
    """The case's own fvSolution, no convergence test, the factors ``text`` from a regular file."""
    (case / "system" / SIMPLE_INCLUDE).write_text(_simple_override(without_convergence_test(cfg)))
    (case / "system" / FIXED_RELAXATION).write_bytes(text)
    own = (base / "system" / "fvSolution").read_text()
    (case / "system" / "fvSolution").write_text(
        f'{own}\n#include "{SIMPLE_INCLUDE}"\n#include "{FIXED_RELAXATION}"\n')


def relaxation_text(cfg: FoamEnvConfig, alpha_u: float, alpha_p: float, flat: bool = False,
                    alpha_t: float | None = None, turbulence: Sequence[str] | None = None) -> bytes:
    """The relaxationFactors entry the bridge feeds through the FIFO for one action.

    It is merged into the case's own relaxationFactors, so every factor it does not name stays the
    case's: alpha_u relaxes the velocity equation, alpha_p the pressure field, and the turbulence
    fields get ``cfg.k_omega_relaxation`` (a float, alpha_u for FOLLOW_ALPHA_U, ``alpha_t`` for
    K_OMEGA_ACTION, nothing for None, nor for K_OMEGA_ACTION without an ``alpha_t``: the case's own).
    ``turbulence``: the fields that factor relaxes (default ``cfg.turbulence_fields``; see
    :func:`turbulence_fields`). ``flat``: the case uses the old flat layout
    (``relaxationFactors { p 0.3; U 0.7; }``).
    """
    fields = {cfg.pressure_field: float(alpha_p)}
    equations = {cfg.velocity_field: float(alpha_u)}
    mode = cfg.k_omega_relaxation
    factor = float(alpha_u) if mode == FOLLOW_ALPHA_U else alpha_t if mode == K_OMEGA_ACTION else mode
    if factor is not None:
        names = cfg.turbulence_fields if turbulence is None else turbulence
        equations.update({name: float(factor) for name in names})
    factors = {**fields, **equations} if flat else {"fields": fields, "equations": equations}
    return FoamFile.dumps({"relaxationFactors": factors}, ensure_header=False) + b"\n"


def turbulence_fields(cfg: FoamEnvConfig, info: CaseInfo) -> tuple[str, ...]:
    """The fields alpha_t relaxes (relax_k_omega="action"): ``cfg.turbulence_fields`` for the built-in
    case; for a user's case, every field its dry run solved besides the velocity and pressure (k and
    omega, k and epsilon, nuTilda...), so that the third action reaches whatever model it runs."""
    if cfg.builtin or not info.solved_fields:
        return tuple(cfg.turbulence_fields)
    from foam_bridge.user_case import solved_field_names  # user_case imports this module

    skip = {cfg.velocity_field, cfg.pressure_field}
    return tuple(name for name in solved_field_names(info.solved_fields) if name not in skip)


def initial_state(info: CaseInfo, inlet_velocity: float | None) -> tuple[float, float]:
    """(mean |U|^2 over the inlet faces, mean |U|^2 over the cells) at iteration 0 of an episode.

    Arithmetic means, as the solver-side function objects compute them later. A set inlet speed is
    uniform over the inlet; otherwise the case's own inlet value counts (0 without one).
    """
    inlet = info.inlet_state if inlet_velocity is None else float(inlet_velocity) ** 2
    return inlet, info.cells_state


def _mean_magnitude_squared(value: Any) -> float:
    if isinstance(value, str):
        return 0.0
    array = np.asarray(value, dtype=float)
    if array.ndim <= 1:
        return float(np.sum(array**2))
    return float(np.mean(np.sum(array**2, axis=-1)))


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def _append(path: Path, text: str) -> None:
    """Append bridge entries to one of the case's own dictionaries (they override by merging)."""
    with open(path, "a") as out:
        out.write(f"\n// ----- appended by foam_bridge for this episode -----\n{text}\n")


def _set_user_inlet(case: Path, cfg: FoamEnvConfig, info: CaseInfo, speed: float) -> None:
    """Inlet U = speed along the case's inlet direction; inlet k/omega from the chosen formula, if any.

    A complete ``fixedValue`` entry under the patch's exact name: it merges into an entry of that name
    and takes precedence over a regular-expression entry that matched the patch.
    """
    vector = " ".join(repr(speed * c) for c in info.inlet_direction)
    _append(case / "0" / cfg.velocity_field, _inlet_override(cfg, f"uniform ({vector})"))
    if cfg.turbulence_formula is None:
        return
    intensity, ratio = cfg.turbulence_formula
    values = dict(zip(("k", "omega"), inlet_turbulence(speed, intensity, ratio, info.nu or math.nan),
                      strict=True))
    for name in _touched_turbulence_fields(cfg):
        _append(case / "0" / name, _inlet_override(cfg, f"uniform {values[name]!r}"))


def _inlet_override(cfg: FoamEnvConfig, value: str) -> str:
    return f"boundaryField\n{{\n    {cfg.inlet_patch}\n    {{\n        type fixedValue;\n" \
           f"        value {value};\n    }}\n}}"


def _set_builtin_inlet(case: Path, cfg: FoamEnvConfig, info: CaseInfo, speed: float) -> None:
    """The built-in template (ours, plain): inlet U along x, inlet and internal k/omega from the paper's
    formula (the template's walls take ``$internalField``, so the internal value is set in place)."""
    with FoamFile(case / "0" / cfg.velocity_field) as velocity:
        velocity["boundaryField"][cfg.inlet_patch]["value"] = speed * np.asarray(info.inlet_direction)
    intensity, ratio = cfg.turbulence_formula or (TURBULENCE_INTENSITY, VISCOSITY_RATIO)
    k, omega = inlet_turbulence(speed, intensity, ratio, info.nu or KINEMATIC_VISCOSITY)
    for name, value in (("k", k), ("omega", omega)):
        if name not in cfg.turbulence_fields:
            continue
        with FoamFile(case / "0" / name) as field:
            field["boundaryField"][cfg.inlet_patch]["value"] = value
            field["internalField"] = value


def _write_control(case: Path, cfg: FoamEnvConfig, pause: bool, functions: bool = True,
                   restart_at: int | None = None, end: int | None = None) -> None:
    """system/foamBridge/controlDict (run control, OptimisationSwitches, functions), #included by
    the case's controlDict. ``restart_at``: start from the latest time (that iteration), write the fields
    at every boundary and pause only after it; ``end``: the last iteration (default max_iterations)."""
    settings = {
        "startFrom": "startTime" if restart_at is None else "latestTime", "startTime": 0,
        "stopAt": "endTime", "endTime": cfg.max_iterations if end is None else end, "deltaT": 1,
        "writeControl": "timeStep",
        "writeInterval": cfg.max_iterations if restart_at is None else cfg.interval,
        "runTimeModifiable": True,
        "OptimisationSwitches": {"fileModificationSkew": 0, "fileModificationChecking": "timeStamp"},
        "functions": _function_objects(cfg, case, pause, restart_at or 0) if functions else {},
    }
    if cfg.case_dir is None:  # the built-in case's results are written losslessly; a user's as theirs
        settings.update({"purgeWrite": 0, "writeFormat": "binary", "writePrecision": 17})
    elif cfg.confirm_alpha_u is not None:  # but a check (and a restart) needs the fields, not a rounding
        settings.update({"purgeWrite": 0, "writePrecision": 17})
    target = case / "system" / CONTROL_INCLUDE
    first = not target.exists()
    target.write_bytes(FoamFile.dumps(settings, ensure_header=False))
    if first:
        _append(case / "system" / "controlDict", f'#include "{CONTROL_INCLUDE}"')


def _function_objects(cfg: FoamEnvConfig, case: Path, pause: bool, after: int = 0) -> dict[str, Any]:
    """The paper's state printed every iteration, then the pause after every ``interval`` iterations
    (only after iteration ``after``: a restarted solver must not swap in the copies of earlier pauses)."""
    every_iteration = {"executeControl": "timeStep", "executeInterval": 1, "writeControl": "timeStep",
                       "writeInterval": 1, "log": True, "writeToFile": False, "writeFields": False}
    functions: dict[str, Any] = {
        "foamBridgeMagSqrU": {"type": "magSqr", "libs": _FIELD_LIBS, "field": cfg.velocity_field,
                              "result": STATE_FIELD, "executeControl": "timeStep", "executeInterval": 1,
                              "writeControl": "none"},
        CELLS_FUNCTION: {"type": "volFieldValue", "libs": _FIELD_LIBS, "fields": [STATE_FIELD],
                         "operation": "average", "regionType": "all", **every_iteration},
        INLET_FUNCTION: {"type": "surfaceFieldValue", "libs": _FIELD_LIBS, "fields": [STATE_FIELD],
                         "operation": "average", "regionType": "patch", "name": cfg.inlet_patch,
                         "surfaceFormat": "none", **every_iteration},
    }
    boundaries = [k for k in pause_boundaries(cfg)[1:] if k > after]
    if pause and boundaries:
        copies = [[k, f'"$FOAM_CASE/system/{BRIDGE_DIR}/{_fv_solution_copy(case, k).name}"']
                  for k in boundaries]
        functions[PAUSE_FUNCTION] = {
            "type": "timeActivatedFileUpdate", "libs": ["libutilityFunctionObjects.so"],
            "executeControl": "timeStep", "executeInterval": 1, "writeControl": "none",
            "fileToUpdate": '"$FOAM_CASE/system/fvSolution"', "timeVsFile": copies}
    return functions


def _write_fv_solution(case: Path, cfg: FoamEnvConfig) -> None:
    """SIMPLE settings and the relaxation FIFO appended to fvSolution; one copy + FIFO per boundary."""
    (case / "system" / SIMPLE_INCLUDE).write_text(_simple_override(cfg))
    path = case / "system" / "fvSolution"
    own = path.read_text()
    for boundary in pause_boundaries(cfg):
        fifo = relaxation_fifo(case, boundary)
        includes = f'#include "{SIMPLE_INCLUDE}"\n#include "{BRIDGE_DIR}/{fifo.name}"'
        target = path if boundary == 0 else _fv_solution_copy(case, boundary)
        if boundary:
            target.write_text(own)
        _append(target, includes)
        os.mkfifo(fifo)


def _simple_override(cfg: FoamEnvConfig) -> str:
    """The case's own SIMPLE dictionary with the bridge's residualControl (and consistent, if set).

    ``#overwrite`` replaces the entry instead of merging into it, so none of the case's own
    residualControl entries (regular expressions included) survives next to the criterion.
    """
    criterion = "".join(f"        {name} {float(value)!r};\n" for name, value in cfg.convergence.items())
    consistent = "" if cfg.variant is None else \
        f"    consistent {'yes' if cfg.variant == 'SIMPLEC' else 'no'};\n"
    return (f"foamBridgeCaseSIMPLE {{ $SIMPLE; }}\n#overwrite SIMPLE\n{{\n    $foamBridgeCaseSIMPLE;\n"
            f"    #remove residualControl\n{consistent}    residualControl\n    {{\n{criterion}    }}\n}}\n"
            f"#remove foamBridgeCaseSIMPLE\n")
