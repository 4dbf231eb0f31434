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
viscosity, mesh and initial field, with ``sample_variations``) and the errors.
Modules whose top says "internal" are the machinery behind these names; their contents may change.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from gymnasium.envs.registration import register, registry

ENV_ID = "foam_bridge/RelaxationControl-v0"

if ENV_ID not in registry:
    register(
        id=ENV_ID,
        entry_point="foam_bridge.gym_envs:RelaxationControlEnv",
        vector_entry_point="foam_bridge.gym_envs:RelaxationControlVecEnv",
    )

#: The module that defines each public name (imported on first access of one of its names).
_HOMES: dict[str, tuple[str, ...]] = {
    "config": ("FoamEnvConfig", "ACTION_NAMES", "BUILTIN_INLET_VELOCITY", "FOLLOW_ALPHA_U", "K_OMEGA_ACTION",
               "MESH_SCALE_USABLE_MIN", "OBSERVATION_BOUND", "PAPER_INLET_TURBULENCE", "REWARDS",
               "SIMPLE_VARIANTS", "STEP_HEIGHT_H", "TEST_CONVERGENCE", "TRAIN_CONVERGENCE", "U_REF",
               "failure_reward"),
    "env": ("FoamCaseEnv", "FAILURES", "OUTCOMES"),
    "batched": ("BatchedFoamEnv",),
    "gym_envs": ("RelaxationControlEnv", "RelaxationControlVecEnv"),
    "backends": ("BACKENDS", "make_backend"),
    "user_case": ("case_defaults",),
    "grid": ("GridCell", "best_cell", "grid_config", "plot_grid", "read_grid_csv", "run_grid",
             "write_grid_csv"),
    "episodes": ("EpisodeJob", "EpisodeRun", "run_episodes"),
    "export": ("export_case",),
    "family": ("FamilyCase", "VARIATION_NAMES", "Variation", "build_family", "read_manifest",
               "sample_variations"),
    "openfoam": ("find_openfoam",),
    "logparse": ("criterion_distance",),
    "errors": ("CaseError", "ClusterError", "OpenFOAMNotFoundError", "PoolLostError", "SolverFailure"),
}
_EXPORTS = {name: f"foam_bridge.{module}" for module, names in _HOMES.items() for name in names}

__all__ = [
    "ACTION_NAMES", "BACKENDS", "BUILTIN_INLET_VELOCITY", "ENV_ID", "FAILURES", "FOLLOW_ALPHA_U",
    "K_OMEGA_ACTION", "MESH_SCALE_USABLE_MIN", "OBSERVATION_BOUND", "OUTCOMES", "PAPER_INLET_TURBULENCE",
    "REWARDS", "SIMPLE_VARIANTS", "STEP_HEIGHT_H", "TEST_CONVERGENCE", "TRAIN_CONVERGENCE", "U_REF",
    "VARIATION_NAMES", "BatchedFoamEnv", "CaseError", "ClusterError", "EpisodeJob", "EpisodeRun",
    "FamilyCase", "FoamCaseEnv", "FoamEnvConfig", "GridCell", "OpenFOAMNotFoundError", "PoolLostError",
    "RelaxationControlEnv", "RelaxationControlVecEnv", "SolverFailure", "Variation", "best_cell",
    "build_family", "case_defaults", "criterion_distance", "export_case", "failure_reward", "find_openfoam",
    "grid_config", "make_backend", "plot_grid", "read_grid_csv", "read_manifest", "run_episodes", "run_grid",
    "sample_variations", "write_grid_csv",
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
    from foam_bridge.backends import BACKENDS, make_backend
    from foam_bridge.batched import BatchedFoamEnv
    from foam_bridge.config import (
        ACTION_NAMES,
        BUILTIN_INLET_VELOCITY,
        FOLLOW_ALPHA_U,
        K_OMEGA_ACTION,
        MESH_SCALE_USABLE_MIN,
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
    )
    from foam_bridge.env import FAILURES, OUTCOMES, FoamCaseEnv
    from foam_bridge.episodes import EpisodeJob, EpisodeRun, run_episodes
    from foam_bridge.errors import (
        CaseError,
        ClusterError,
        OpenFOAMNotFoundError,
        PoolLostError,
        SolverFailure,
    )
    from foam_bridge.export import export_case
    from foam_bridge.family import (
        VARIATION_NAMES,
        FamilyCase,
        Variation,
        build_family,
        read_manifest,
        sample_variations,
    )
    from foam_bridge.grid import (
        GridCell,
        best_cell,
        grid_config,
        plot_grid,
        read_grid_csv,
        run_grid,
        write_grid_csv,
    )
    from foam_bridge.gym_envs import RelaxationControlEnv, RelaxationControlVecEnv
    from foam_bridge.logparse import criterion_distance
    from foam_bridge.openfoam import find_openfoam
    from foam_bridge.user_case import case_defaults
