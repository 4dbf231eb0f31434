"""One OpenFOAM case = one environment: the paper's solver-control MDP on a persistent simpleFoam.

MDP (Pawar & Maulik, "Solver convergence acceleration"):

- action: (alpha_u, alpha_p), clipped into ``[action_low, action_high]``; alpha_u relaxes the velocity
  equation (and k/omega unless ``relax_k_omega`` fixes them), alpha_p the pressure field.
- observation: ``(mean_inlet |U|^2 + mean_cells |U|^2) / state_scale`` (arithmetic means over the inlet
  faces and over all cells, as the paper's state; ``state_scale`` = 44.2**2 by default), then
  optionally the log10 initial residuals of the last ``residual_features`` step boundaries.
- reward: -(K_t - K_{t-1}), K = SIMPLE iterations actually run; the return is minus the total.
- episode end: the solver's own ``SIMPLE.residualControl`` met (``converged``, terminated), the
  ``max_iterations`` cap (``truncated``), or a failure (terminated, with the failure penalty):
  ``crashed`` (solver died, broken case), ``diverged`` (NaN/Inf or residual above the threshold),
  ``hung`` (the step watchdog fired).

One simpleFoam process runs per episode. It pauses itself after every ``interval`` iterations inside a
``systemCall`` function object that blocks on a FIFO (see foam_bridge.solver); while it is paused the
bridge writes the new fvSolution atomically and releases it. When factors take effect: OpenFOAM's
``Time::run()`` re-reads modified files *before* it executes function objects, so factors written at
the pause after iteration K are read after iteration K+1: iteration K+1 still runs with the previous
action and the new action governs iterations K+2 .. K+interval+1. The first action of an episode is
written before the solver starts and governs iterations 1 .. interval+1. This lag of one iteration is
deterministic and tested (tests/test_foam_env.py); constant factors are unaffected (chunked ==
uninterrupted).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from foam_bridge.config import FoamEnvConfig
from jaxsimrl.envs.protocol import BoxSpec, Step

#: Every value of ``info["outcome"]``.
OUTCOMES = ("running", "converged", "truncated", "crashed", "diverged", "hung")
#: Outcomes that are a failure of the solver (terminated, with the failure penalty).
FAILURES = ("crashed", "diverged", "hung")


class FoamCaseEnv:
    """One case directory, one persistent simpleFoam per episode; gymnasium-style, host side.

    ``FoamCaseEnv(cfg, work_dir=None, env_id=0)`` validates ``cfg`` (``ValueError``), locates
    OpenFOAM (``foam_bridge.errors.OpenFOAMNotFoundError`` naming how to install it), checks a user's
    ``case_dir`` (``foam_bridge.errors.CaseError``, a ValueError) and builds the base case (mesh) once
    under ``work_dir/env_<env_id>``. Every episode runs in a fresh copy of that base case.

    ``reset(seed=None, options=None) -> (obs, info)``: ends any running episode (kills the solver's
    process group), samples the inlet velocity from the episode RNG (re-seeded when ``seed`` is given;
    ``options={"inlet_velocity": v}`` fixes it), writes the case. The solver starts on the first step.

    ``step(action) -> (obs, reward, terminated, truncated, info)``; ``info`` has "iterations" (K),
    "residuals" ({field: latest initial residual}), "outcome" (one of OUTCOMES), "cause" (failure text
    or ""), "inlet_velocity", and "episode" (the episode record) on the step that ended the episode.
    Stepping a finished episode raises ``RuntimeError`` (no auto-reset here).

    ``close()`` kills the solver's whole process group and removes the case (unless keep_cases).
    """

    def __init__(self, cfg: FoamEnvConfig, work_dir: Any = None, env_id: int = 0) -> None:
        raise NotImplementedError("FoamCaseEnv is being implemented")

    @property
    def observation_space_spec(self) -> BoxSpec:
        """Box of the observation: the state (>= 0) then the log10 residual features."""
        raise NotImplementedError

    @property
    def action_space_spec(self) -> BoxSpec:
        """Box of (alpha_u, alpha_p): ``[action_low, action_high]``."""
        raise NotImplementedError

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Start a new episode; returns the initial observation (iteration 0) and info."""
        raise NotImplementedError

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Run ``interval`` SIMPLE iterations with the given factors; see the class docstring."""
        raise NotImplementedError

    def close(self) -> None:
        """Kill the solver's process group (no orphans) and remove the case directories."""
        raise NotImplementedError


class FoamEnv:
    """The protocol form (jaxsimrl.envs.protocol.Environment) of one foam case, with numpy values.

    ``reset(key, params)`` and ``step(key, state, action, params)``: ``key`` is an int seed or an
    integer array (e.g. ``jax.random.key_data(key)``: it is hashed into a numpy seed); ``params`` is a
    FoamEnvConfig; ``state`` is a host-side handle (:class:`FoamEnvState`). The underlying
    FoamCaseEnv is created on the first reset and recreated when ``params`` change.
    """

    def __init__(self, work_dir: Any = None, env_id: int = 0) -> None:
        raise NotImplementedError

    def default_params(self) -> FoamEnvConfig:
        return FoamEnvConfig()

    def reset(self, key: Any, params: FoamEnvConfig) -> tuple[np.ndarray, Any]:
        raise NotImplementedError

    def step(self, key: Any, state: Any, action: Any, params: FoamEnvConfig) -> Step:
        raise NotImplementedError

    def observation_space(self, params: FoamEnvConfig) -> BoxSpec:
        raise NotImplementedError

    def action_space(self, params: FoamEnvConfig) -> BoxSpec:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError
