"""Policy rollouts over batches of full episodes (jitted, vmapped) and their returns."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxsimrl.agents.ppo.policy import Policy

# act(obs (B, obs_dim), carry, starts (B,), key) -> (actions (B, action_dim), carry)
ActFn = Callable[[jax.Array, Any, jax.Array, jax.Array], tuple[jax.Array, Any]]


def scan_episodes(env: Any, env_params: Any, act: ActFn, carry: Any, start: tuple[jax.Array, Any],
                  key: jax.Array, steps: int, record: Callable[[Any], Any]) -> Any:
    """Run the batch of episodes ``start`` = (obs, env state) for ``steps`` steps under ``act``.

    Step t acts with ``fold_in(key, t)`` and steps every env with ``key``; the first step is flagged
    as an episode start. Returns ``record(step)`` of every env step, stacked time-major (steps, B, ...).
    Trace it inside ``jit``.
    """
    obs, state = start
    first = jnp.ones(obs.shape[0], bool)

    def step(loop: tuple, t: jax.Array) -> tuple[tuple, Any]:
        obs, state, carry = loop
        action, carry = act(obs, carry, first & (t == 0), jax.random.fold_in(key, t))
        out = jax.vmap(env.step, in_axes=(None, 0, 0, None))(key, state, action, env_params)
        return (out.obs, out.state, carry), record(out)

    return jax.lax.scan(step, (obs, state, carry), jnp.arange(steps))[1]


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
    start = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(reset_key, num_episodes), env_params)

    def act(obs: jax.Array, carry: Any, starts: jax.Array, key: jax.Array) -> tuple[jax.Array, Any]:
        return policy.act(state_or_params, obs, carry, starts, key, deterministic)

    reward, done = scan_episodes(env, env_params, act, policy.initial_carry(num_episodes), start, act_key,
                                 steps, lambda out: (out.reward, out.terminated | out.truncated))
    ended_before = (jnp.cumsum(done, axis=0) - done) > 0  # an earlier step ended the episode
    return jnp.sum(jnp.where(ended_before, 0.0, reward), axis=0)


_returns = jax.jit(_returns, static_argnums=(0, 2, 5, 6, 7))
