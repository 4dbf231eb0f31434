"""foam_bridge: OpenFOAM's simpleFoam as a reinforcement-learning environment (solver control).

Everything a user of the plugin needs is a name of this package (``from foam_bridge import
FoamCaseEnv, FoamEnvConfig``); the modules behind them are listed in ``_EXPORTS``. Those names load
on first use, so importing the package only registers the gymnasium ids (nothing heavy, no JAX):

- ``foam_bridge/RelaxationControl-v0``: one case, ``gymnasium.make(ID, mesh_scale=0.5, ...)``;
  ``gymnasium.make_vec(ID, num_envs=N, pool=P, ...)`` gives the pooled vector env
  (RelaxationControlVecEnv).

The names: the configuration (FoamEnvConfig and the constants its fields take), the envs (FoamCaseEnv:
one case; BatchedFoamEnv: N cases on a process pool or Ray, ``make_backend`` for the pool alone; the
gymnasium envs), a user's case's own MDP (``case_defaults``), the episode pool (``run_episodes``: a
queue of ``EpisodeJob``s, each with its own reset options and controller, on the local worker pool),
the constant-factor grid study (``run_grid`` ...), ``export_case`` (an episode's case as a plain
OpenFOAM case), case families (``build_family``: N variants of a case, varied in speed, angle,
viscosity, mesh and initial field, with ``sample_variations``) and the errors; then what an
application built on the bridge (jaxsimrl's OpenFOAM application) drives it with: the worker backends and
their requests, the asynchronous batch, the case checks, MPI decomposition and reconstruction, the log
parser, the episode records and the public module ``foamdict`` (OpenFOAM dictionaries, as foamDictionary
expands them). jaxsimrl imports nothing else of foam_bridge (tests/test_plugin_boundary.py).
The modules behind these names are private (``_name``, as foamlib's): their contents may change.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from gymnasium.envs.registration import register, registry

ENV_ID = "foam_bridge/RelaxationControl-v0"

if ENV_ID not in registry:
    register(
        id=ENV_ID,
        entry_point="foam_bridge._gym_envs:RelaxationControlEnv",
        vector_entry_point="foam_bridge._gym_envs:RelaxationControlVecEnv",
    )

#: The module that defines each public name (imported on first access of one of its names).
_HOMES: dict[str, tuple[str, ...]] = {
    "_config": (
        "ACTION_NAMES", "BUILTIN_INLET_VELOCITY", "BUILTIN_RELAX_K_OMEGA", "FOLLOW_ALPHA_U",
        "K_OMEGA_ACTION", "MESH_SCALE_USABLE_MIN", "NEVER_CONVERGED", "OBSERVATION_BOUND",
        "PAPER_INLET_TURBULENCE", "REWARDS", "SIMPLE_VARIANTS", "STEP_HEIGHT_H", "TEST_CONVERGENCE",
        "TRAIN_CONVERGENCE", "U_REF", "FoamEnvConfig", "failure_reward", "without_convergence_test",
    ),
    "_env": ("CASE_STOP", "FAILURES", "OUTCOMES", "FoamCaseEnv"),
    "_batched": ("BatchedFoamEnv",),
    "_gym_envs": ("RelaxationControlEnv", "RelaxationControlVecEnv"),
    "_backends": ("BACKENDS", "BAD_INPUT_ERRORS", "Reply", "Request", "make_backend", "validate_pool"),
    "_user_case": ("CASE_DEFAULT_FIELDS", "case_defaults"),
    "_grid": (
        "Condition", "GridCell", "best_cell", "grid_config", "plot_grid", "plot_grid_slices",
        "read_grid_csv", "run_grid", "write_grid_csv",
    ),
    "_episodes": (
        "ConstantFactors", "EpisodeJob", "EpisodeRun", "StatelessController", "StepRecord", "run_episodes",
    ),
    "_export": ("POST_PROCESSING", "export_case", "latest_time"),
    "_family": (
        "VARIATION_NAMES", "FamilyCase", "Variation", "build_family", "read_manifest", "sample_variations",
    ),
    "_generator_specs": ("GEOMETRY_KINDS", "CaseSpec", "sample_specs"),
    "_generator": ("GeneratedCase", "generate_cases", "read_generated", "write_case"),
    "_openfoam": ("find_openfoam",),
    "_logparse": ("LogParser", "SolverCost", "criterion_distance", "field_residual", "solved_field_names"),
    "_errors": (
        "CaseError", "ClusterError", "NoResidualControl", "OpenFOAMNotFoundError", "PoolLostError",
        "SolverFailure",
    ),
    "_async_batch": ("AsyncFoamEnv",),
    "_records": ("COLUMNS", "EpisodeRecord", "read_rows", "rows_to_csv"),
    "_episode_case": ("CaseInfo",),
    "_family_env": ("FamilyFactory",),
    "_backends.local": ("LocalBackend",),
    "_timing": ("TimedSteps",),
    "_spaces": ("action_spec", "factors_of", "shares_of"),
    "_base_case": ("check_case", "check_case_files", "declared_patches"),
    "_template": ("copy_case", "run_application"),
    "_parallel": (
        "decompose", "mpirun_path", "processor_count", "reconstruct", "reconstruct_into",
        "reconstructed_case",
    ),
    "_backends.reaper": ("kill_processes_under",),
    "_fields": ("read_internal_field", "relative_l2", "time_directories"),
    "_solver": ("run_to_end",),
    "_function_objects": (
        "FunctionObjectTable", "TableReader", "final_rows", "quantity_name", "relative_difference",
        "row_scale", "time_series",
    ),
    "_answer_monitor": ("AnswerMonitor", "restore_case"),
    "_settle_verdict": ("DEFAULT_TOLERANCE", "SETTLED", "SettleRule", "Verdict"),
    "_iterative_error": ("QuantityTrack",),
}
_EXPORTS = {name: f"foam_bridge.{module}" for module, names in _HOMES.items() for name in names}
#: Public modules: ``from foam_bridge import foamdict`` (imported as the package's submodule).
_MODULES = ("foamdict",)

__all__ = [
    "ACTION_NAMES", "AnswerMonitor", "AsyncFoamEnv", "BACKENDS", "BAD_INPUT_ERRORS",
    "BUILTIN_INLET_VELOCITY", "BUILTIN_RELAX_K_OMEGA", "BatchedFoamEnv", "CASE_DEFAULT_FIELDS", "CASE_STOP",
    "COLUMNS", "CaseError", "CaseInfo", "CaseSpec", "ClusterError", "Condition", "ConstantFactors",
    "DEFAULT_TOLERANCE", "ENV_ID", "EpisodeJob", "EpisodeRecord", "EpisodeRun", "FAILURES",
    "FOLLOW_ALPHA_U", "FamilyCase", "FamilyFactory", "FoamCaseEnv", "FoamEnvConfig", "FunctionObjectTable",
    "GEOMETRY_KINDS", "GeneratedCase", "GridCell", "K_OMEGA_ACTION", "LocalBackend", "LogParser",
    "MESH_SCALE_USABLE_MIN", "NEVER_CONVERGED", "NoResidualControl", "OBSERVATION_BOUND", "OUTCOMES",
    "OpenFOAMNotFoundError", "PAPER_INLET_TURBULENCE", "POST_PROCESSING", "PoolLostError", "QuantityTrack",
    "REWARDS", "RelaxationControlEnv", "RelaxationControlVecEnv", "Reply", "Request", "SETTLED",
    "SIMPLE_VARIANTS", "STEP_HEIGHT_H", "SettleRule", "SolverCost", "SolverFailure", "StatelessController",
    "StepRecord", "TEST_CONVERGENCE", "TRAIN_CONVERGENCE", "TableReader", "TimedSteps", "U_REF",
    "VARIATION_NAMES", "Variation", "Verdict", "action_spec", "best_cell", "build_family", "case_defaults",
    "check_case", "check_case_files", "copy_case", "criterion_distance", "declared_patches", "decompose",
    "export_case", "factors_of", "failure_reward", "field_residual", "final_rows", "find_openfoam",
    "foamdict", "generate_cases", "grid_config", "kill_processes_under", "latest_time", "make_backend",
    "mpirun_path", "plot_grid", "plot_grid_slices", "processor_count", "quantity_name", "read_generated",
    "read_grid_csv", "read_internal_field", "read_manifest", "read_rows", "reconstruct", "reconstruct_into",
    "reconstructed_case", "relative_difference", "relative_l2", "restore_case", "row_scale", "rows_to_csv",
    "run_application", "run_episodes", "run_grid", "run_to_end", "sample_specs", "sample_variations",
    "shares_of", "solved_field_names", "time_directories", "time_series", "validate_pool",
    "without_convergence_test", "write_case", "write_grid_csv",
]


def __getattr__(name: str) -> Any:
    """Load an exported name from its module on first access (PEP 562)."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'foam_bridge' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later accesses skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


if TYPE_CHECKING:  # what type checkers and editors see; at run time __getattr__ loads these
    from foam_bridge import foamdict
    from foam_bridge._answer_monitor import AnswerMonitor, restore_case
    from foam_bridge._async_batch import AsyncFoamEnv
    from foam_bridge._backends import BACKENDS, BAD_INPUT_ERRORS, Reply, Request, make_backend, validate_pool
    from foam_bridge._backends.local import LocalBackend
    from foam_bridge._backends.reaper import kill_processes_under
    from foam_bridge._base_case import check_case, check_case_files, declared_patches
    from foam_bridge._batched import BatchedFoamEnv
    from foam_bridge._config import (
        ACTION_NAMES,
        BUILTIN_INLET_VELOCITY,
        BUILTIN_RELAX_K_OMEGA,
        FOLLOW_ALPHA_U,
        K_OMEGA_ACTION,
        MESH_SCALE_USABLE_MIN,
        NEVER_CONVERGED,
        OBSERVATION_BOUND,
        PAPER_INLET_TURBULENCE,
        REWARDS,
        SIMPLE_VARIANTS,
        STEP_HEIGHT_H,
        TEST_CONVERGENCE,
        TRAIN_CONVERGENCE,
        U_REF,
        FoamEnvConfig,
        failure_reward,
        without_convergence_test,
    )
    from foam_bridge._env import CASE_STOP, FAILURES, OUTCOMES, FoamCaseEnv
    from foam_bridge._episode_case import CaseInfo
    from foam_bridge._episodes import (
        ConstantFactors,
        EpisodeJob,
        EpisodeRun,
        StatelessController,
        StepRecord,
        run_episodes,
    )
    from foam_bridge._errors import (
        CaseError,
        ClusterError,
        NoResidualControl,
        OpenFOAMNotFoundError,
        PoolLostError,
        SolverFailure,
    )
    from foam_bridge._export import POST_PROCESSING, export_case, latest_time
    from foam_bridge._family import (
        VARIATION_NAMES,
        FamilyCase,
        Variation,
        build_family,
        read_manifest,
        sample_variations,
    )
    from foam_bridge._family_env import FamilyFactory
    from foam_bridge._fields import read_internal_field, relative_l2, time_directories
    from foam_bridge._function_objects import (
        FunctionObjectTable,
        TableReader,
        final_rows,
        quantity_name,
        relative_difference,
        row_scale,
        time_series,
    )
    from foam_bridge._generator import GeneratedCase, generate_cases, read_generated, write_case
    from foam_bridge._generator_specs import GEOMETRY_KINDS, CaseSpec, sample_specs
    from foam_bridge._grid import (
        Condition,
        GridCell,
        best_cell,
        grid_config,
        plot_grid,
        plot_grid_slices,
        read_grid_csv,
        run_grid,
        write_grid_csv,
    )
    from foam_bridge._gym_envs import RelaxationControlEnv, RelaxationControlVecEnv
    from foam_bridge._iterative_error import QuantityTrack
    from foam_bridge._logparse import (
        LogParser,
        SolverCost,
        criterion_distance,
        field_residual,
        solved_field_names,
    )
    from foam_bridge._openfoam import find_openfoam
    from foam_bridge._parallel import (
        decompose,
        mpirun_path,
        processor_count,
        reconstruct,
        reconstruct_into,
        reconstructed_case,
    )
    from foam_bridge._records import COLUMNS, EpisodeRecord, read_rows, rows_to_csv
    from foam_bridge._settle_verdict import DEFAULT_TOLERANCE, SETTLED, SettleRule, Verdict
    from foam_bridge._solver import run_to_end
    from foam_bridge._spaces import action_spec, factors_of, shares_of
    from foam_bridge._template import copy_case, run_application
    from foam_bridge._timing import TimedSteps
    from foam_bridge._user_case import CASE_DEFAULT_FIELDS, case_defaults
