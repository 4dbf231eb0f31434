"""Mean return of a policy over full episodes from random initial states (jitted, vmapped)."""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxsimrl.agents.ppo.policy import Policy


def episode_returns(policy: Policy, state_or_params: Any, env: Any, env_params: Any, key: jax.Array,
                    num_episodes: int = 32, deterministic: bool = True) -> np.ndarray:
    """Undiscounted returns of ``num_episodes`` episodes of ``env_params.horizon`` steps each.

    Episode i starts from ``env.reset(split(key, num_episodes)[i])``, so the same key gives the same
    initial states for any policy (fair before/after comparisons).
    """
    steps = env_params.horizon
    returns = _returns(policy, state_or_params, env, env_params, key, num_episodes, deterministic, steps)
    return np.asarray(returns)


def _returns(policy: Policy, state_or_params: Any, env: Any, env_params: Any, key: jax.Array,
             num_episodes: int, deterministic: bool, steps: int) -> jax.Array:
    reset_key, act_key = jax.random.split(key)
    obs, env_state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(reset_key, num_episodes),
                                                            env_params)
    carry = policy.initial_carry(num_episodes)
    first = jnp.ones(num_episodes, bool)

    def step(loop: tuple, t: jax.Array) -> tuple[tuple, None]:
        obs, env_state, carry, alive, total = loop
        starts = first & (t == 0)
        action, carry = policy.act(state_or_params, obs, carry, starts, jax.random.fold_in(act_key, t),
                                   deterministic)
        out = jax.vmap(env.step, in_axes=(None, 0, 0, None))(act_key, env_state, action, env_params)
        total = total + jnp.where(alive, out.reward, 0.0)
        alive = alive & ~(out.terminated | out.truncated)
        return (out.obs, out.state, carry, alive, total), None

    init = (obs, env_state, carry, first, jnp.zeros(num_episodes, jnp.float32))
    (_, _, _, _, total), _ = jax.lax.scan(step, init, jnp.arange(steps))
    return total


_returns = jax.jit(_returns, static_argnums=(0, 2, 5, 6, 7))
