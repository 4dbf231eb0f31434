"""The episode case: a fresh copy of the base case (foam_bridge._base_case) with the bridge's machinery.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

:func:`write_episode_case` (every episode) copies ``base/`` to a fresh directory (the mesh is
symlinked) and installs the machinery; :func:`write_restart` and :func:`write_check_case` make it go on
from its own fields, or copy it for one checking iteration (foam_bridge._confirm);
:func:`make_uninterrupted` turns it into a plain case with constant factors.

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
"""

from __future__ import annotations

import math
import os
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from foamlib import FoamFile

from foam_bridge._config import FOLLOW_ALPHA_U, K_OMEGA_ACTION, FoamEnvConfig, without_convergence_test
from foam_bridge._fields import time_directory
from foam_bridge._logparse import solved_field_names
from foam_bridge._openfoam import OpenFOAM, find_openfoam
from foam_bridge._parallel import decompose, reconstruct_into
from foam_bridge._template import KINEMATIC_VISCOSITY, TURBULENCE_INTENSITY, VISCOSITY_RATIO, inlet_turbulence

__all__ = ["BRIDGE_DIR", "CELLS_FUNCTION", "CONTROL_INCLUDE", "FIXED_RELAXATION", "INLET_FUNCTION",
           "PAUSE_FUNCTION", "SIMPLE_INCLUDE", "STATE_FIELD", "CaseInfo", "initial_state",
           "make_uninterrupted", "pause_boundaries", "relaxation_fifo", "relaxation_text",
           "touched_turbulence_fields", "turbulence_fields", "write_check_case", "write_control",
           "write_episode_case", "write_fixed_fv_solution", "write_restart"]

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


def write_episode_case(base: Path, dest: Path, cfg: FoamEnvConfig, inlet_velocity: float | None,
                       info: CaseInfo, openfoam: OpenFOAM | None = None) -> None:
    """Fresh episode case in ``dest`` from the meshed ``base``: inlet, controlDict, fvSolution, FIFOs.

    ``inlet_velocity`` None keeps the case's own inlet (a user's case without ``inlet_velocity``).
    With ``cfg.ranks`` > 1 the case is decomposed (``openfoam``'s decomposePar) once its fields and
    controlDict are final and before fvSolution #includes a FIFO, which decomposePar would block on.
    """
    if dest.exists():
        shutil.rmtree(dest)
    shutil.copytree(base, dest, ignore=shutil.ignore_patterns("polyMesh", "log.*"))
    (dest / "constant" / "polyMesh").symlink_to((base / "constant" / "polyMesh").resolve())
    (dest / "system" / BRIDGE_DIR).mkdir()
    if inlet_velocity is not None:
        set_inlet = _set_builtin_inlet if cfg.case_dir is None else _set_user_inlet
        set_inlet(dest, cfg, info, inlet_velocity)
    write_control(dest, cfg, pause=True)
    if cfg.ranks > 1:
        decompose(dest, openfoam or find_openfoam(cfg.openfoam_path), cfg.ranks)
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
    write_control(case, cfg, pause=False, functions=functions)


def write_restart(case: Path, base: Path, cfg: FoamEnvConfig, time: int, text: bytes) -> None:
    """Make the episode case go on from the fields it wrote at iteration ``time`` (foam_bridge._confirm).

    simpleFoam then starts from ``latestTime`` with the factors ``text`` (read from a regular file, so
    the start-up does not pause), without a convergence test of its own (the bridge tests at the step
    boundaries), writes its fields at every boundary (the bridge's checks read them) and pauses at the
    boundaries after ``time``, as before.
    """
    write_fixed_fv_solution(case, base, cfg, text)
    write_control(case, cfg, pause=True, restart_at=time)


def write_check_case(case: Path, base: Path, dest: Path, cfg: FoamEnvConfig, time: int, text: bytes,
                     openfoam: OpenFOAM | None = None) -> None:
    """A copy of the episode case in ``dest`` that runs one SIMPLE iteration from the fields of ``time``
    with the factors ``text`` and no convergence test (foam_bridge._confirm); nothing is written. A
    decomposed episode's fields of ``time`` are reconstructed into ``dest`` (``openfoam``'s
    reconstructPar): the check itself runs serial."""
    if dest.exists():
        shutil.rmtree(dest)
    dest.mkdir(parents=True)
    for part in ("system", "constant"):
        shutil.copytree(case / part, dest / part, symlinks=True,
                        ignore=lambda directory, names: {n for n in names if n.startswith(("relaxation.",
                                                                                             "fvSolution."))})
    write_fixed_fv_solution(dest, base, cfg, text)
    write_control(dest, cfg, pause=False, functions=False, restart_at=time, end=time + 1)
    if cfg.ranks > 1:
        written = time_directory(case / "processor0", cfg.start_time + time)
        reconstruct_into(case, dest, openfoam or find_openfoam(cfg.openfoam_path),
                         str(cfg.start_time + time) if written is None else written.name)
        return
    written = time_directory(case, cfg.start_time + time) or case / str(cfg.start_time + time)
    shutil.copytree(written, dest / written.name)


def write_fixed_fv_solution(case: Path, base: Path, cfg: FoamEnvConfig, text: bytes) -> None:
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
    factor = turbulence_factor(cfg, alpha_u, alpha_t)
    if factor is not None:
        names = cfg.turbulence_fields if turbulence is None else turbulence
        equations.update({name: float(factor) for name in names})
    factors = {**fields, **equations} if flat else {"fields": fields, "equations": equations}
    return FoamFile.dumps({"relaxationFactors": factors}, ensure_header=False) + b"\n"


def turbulence_factor(cfg: FoamEnvConfig, alpha_u: float, alpha_t: float | None = None) -> float | None:
    """The factor one action gives the turbulence fields (see :func:`relaxation_text`): alpha_u for
    FOLLOW_ALPHA_U, ``alpha_t`` for K_OMEGA_ACTION, the fixed factor, or None (the case's own)."""
    mode = cfg.k_omega_relaxation
    return float(alpha_u) if mode == FOLLOW_ALPHA_U else alpha_t if mode == K_OMEGA_ACTION else mode


def turbulence_fields(cfg: FoamEnvConfig, info: CaseInfo) -> tuple[str, ...]:
    """The fields alpha_t relaxes (relax_k_omega="action"): ``cfg.turbulence_fields`` for the built-in
    case; for a user's case, every field its dry run solved besides the velocity and pressure (k and
    omega, k and epsilon, nuTilda...), so that the third action reaches whatever model it runs."""
    if cfg.builtin or not info.solved_fields:
        return tuple(cfg.turbulence_fields)
    skip = {cfg.velocity_field, cfg.pressure_field}
    return tuple(name for name in solved_field_names(info.solved_fields) if name not in skip)


def initial_state(info: CaseInfo, inlet_velocity: float | None) -> tuple[float, float]:
    """(mean |U|^2 over the inlet faces, mean |U|^2 over the cells) at iteration 0 of an episode.

    Arithmetic means, as the solver-side function objects compute them later. A set inlet speed is
    uniform over the inlet; otherwise the case's own inlet value counts (0 without one).
    """
    inlet = info.inlet_state if inlet_velocity is None else float(inlet_velocity) ** 2
    return inlet, info.cells_state


def touched_turbulence_fields(cfg: FoamEnvConfig) -> list[str]:
    """Turbulence fields whose files the bridge edits (inlet k/omega from a formula)."""
    if cfg.turbulence_formula is None:
        return []
    return [name for name in ("k", "omega") if name in cfg.turbulence_fields]


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
    for name in touched_turbulence_fields(cfg):
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


def write_control(case: Path, cfg: FoamEnvConfig, pause: bool, functions: bool = True,
                   restart_at: int | None = None, end: int | None = None) -> None:
    """system/foamBridge/controlDict (run control, OptimisationSwitches, functions), #included by
    the case's controlDict. ``restart_at``: start from the latest time (that iteration), write the fields
    at every boundary and pause only after it; ``end``: the last iteration (default max_iterations).
    Iterations count from ``cfg.start_time``: iteration K is the solver's time start_time + K."""
    start = cfg.start_time
    settings = {
        "startFrom": "startTime" if restart_at is None else "latestTime", "startTime": start,
        "stopAt": "endTime", "endTime": start + (cfg.max_iterations if end is None else end), "deltaT": 1,
        "writeControl": "timeStep",
        "writeInterval": cfg.max_iterations if restart_at is None else cfg.interval,
        "runTimeModifiable": True,
        "OptimisationSwitches": _switches(cfg),
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


def _switches(cfg: FoamEnvConfig) -> dict[str, Any]:
    """Re-read a modified file at once; in parallel on the master only, which opens the FIFO and
    broadcasts fvSolution to the other ranks (foam_bridge._parallel says why: with ``timeStamp`` every
    rank opens the FIFO and the ranks' re-reads come an iteration late)."""
    if cfg.ranks <= 1:
        return {"fileModificationSkew": 0, "fileModificationChecking": "timeStamp"}
    return {"fileModificationSkew": 0, "fileModificationChecking": "timeStampMaster",
            "fileHandler": "uncollated"}


def _function_objects(cfg: FoamEnvConfig, case: Path, pause: bool, after: int = 0) -> dict[str, Any]:
    """The paper's state printed every ``state_interval`` iterations (every step boundary), then the pause
    after every ``interval`` iterations (only after iteration ``after``: a restarted solver must not swap
    in the copies of earlier pauses)."""
    every = cfg.state_interval
    state_every = {"executeControl": "timeStep", "executeInterval": every, "writeControl": "timeStep",
                   "writeInterval": every, "log": True, "writeToFile": False, "writeFields": False}
    functions: dict[str, Any] = {
        "foamBridgeMagSqrU": {"type": "magSqr", "libs": _FIELD_LIBS, "field": cfg.velocity_field,
                              "result": STATE_FIELD, "executeControl": "timeStep", "executeInterval": every,
                              "writeControl": "none"},
        CELLS_FUNCTION: {"type": "volFieldValue", "libs": _FIELD_LIBS, "fields": [STATE_FIELD],
                         "operation": "average", "regionType": "all", **state_every},
    }
    if cfg.inlet_patch is not None:  # a case without an inlet observes its cells alone
        functions[INLET_FUNCTION] = {
            "type": "surfaceFieldValue", "libs": _FIELD_LIBS, "fields": [STATE_FIELD], "operation": "average",
            "regionType": "patch", "name": cfg.inlet_patch, "surfaceFormat": "none", **state_every}
    boundaries = [k for k in pause_boundaries(cfg)[1:] if k > after]
    if pause and boundaries:  # at the solver's times: start_time + K
        copies = [[cfg.start_time + k, f'"$FOAM_CASE/system/{BRIDGE_DIR}/{_fv_solution_copy(case, k).name}"']
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
