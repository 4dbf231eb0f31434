"""foam_bridge: OpenFOAM's simpleFoam as a reinforcement-learning environment (solver control).

Importing the package only registers the gymnasium ids (string entry points, nothing heavy is
imported; no JAX):

- ``foam_bridge/RelaxationControl-v0``: one case, ``gymnasium.make(ID, mesh_scale=0.5, ...)``;
  ``gymnasium.make_vec(ID, num_envs=N, pool=P, ...)`` gives the pooled vector env
  (foam_bridge.gym_envs.RelaxationControlVecEnv).

The library API: foam_bridge.config.FoamEnvConfig, foam_bridge.env.FoamCaseEnv (one case),
foam_bridge.batched.BatchedFoamEnv (N cases on a process pool or Ray), foam_bridge.grid (constant-factor
grid study).
"""

from __future__ import annotations

from gymnasium.envs.registration import register, registry

ENV_ID = "foam_bridge/RelaxationControl-v0"

if ENV_ID not in registry:
    register(
        id=ENV_ID,
        entry_point="foam_bridge.gym_envs:RelaxationControlEnv",
        vector_entry_point="foam_bridge.gym_envs:RelaxationControlVecEnv",
    )

__all__ = ["ENV_ID"]
