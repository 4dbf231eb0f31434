"""jaxsimrl: deep RL (pure-JAX PPO) for controlling scientific simulations.

Importing the package stays light (no JAX): it only registers the gymnasium id
``jaxsimrl/Lorenz-v0`` with a string entry point, so JAX loads when the env is first made, and
``jaxsimrl.load_policy`` (:func:`jaxsimrl.introspect.load_policy`: a trained policy that acts and rolls
itself out) imports JAX on first use. The layers below the CLI, bottom up: envs and runs, agents.ppo
(PPO and the one inference function), policy (a run's trained policy), evaluation, introspect, solve.
"""

from __future__ import annotations

from typing import Any

import gymnasium

LORENZ_ENV_ID = "jaxsimrl/Lorenz-v0"

if LORENZ_ENV_ID not in gymnasium.registry:  # re-imports (importlib.reload) must not warn about overrides
    # max_episode_steps=None: the env terminates its own episodes after LorenzParams.episode_steps.
    gymnasium.register(id=LORENZ_ENV_ID, entry_point="jaxsimrl.envs.gym_lorenz:LorenzGymEnv",
                       max_episode_steps=None)


def __getattr__(name: str) -> Any:
    if name == "load_policy":  # lazily: the introspection API imports JAX
        from jaxsimrl.introspect.loading import load_policy

        return load_policy
    raise AttributeError(f"module 'jaxsimrl' has no attribute {name!r}")
