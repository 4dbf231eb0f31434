"""Roll a loaded policy out in its (pure-JAX) env and keep everything a scientist may want to look at.

One jitted ``lax.scan`` over time, the episodes vmapped. Row ``t`` of the record describes one step:
the observation the policy acted on, the env state it was in, what the network made of it, and what
the env answered. Keys (arrays shaped (episodes, steps, ...), numpy):

- ``obs``: raw observation acted on; ``state.<field>``: every field of the env state at that time
  (for Lorenz ``state.xyz``, ``state.velocity``, ``state.t``, ...);
- ``action`` (env units), ``value`` (critic, reward units), ``hidden`` and ``cell``: the LSTM's h and c
  after reading ``obs`` (recurrent networks only);
- ``reward``, ``terminated``, ``truncated`` and ``info.<name>`` (e.g. ``info.speed``) of the env step.

Episodes are not restarted: a whole episode is the default length.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxsimrl.agents.ppo.acting import forward, sample_batch


def rollout(policy: Any, env_params: Any = None, steps: int | None = None, episodes: int = 1, seed: int = 0,
            deterministic: bool = True) -> dict[str, np.ndarray]:
    """The record of ``episodes`` episodes of ``steps`` steps of ``policy`` (a LoadedPolicy)."""
    params = policy.env_params if env_params is None else env_params
    if steps is None:
        if not hasattr(params, "horizon"):
            raise ValueError("give steps: these env params define no episode length (horizon)")
        steps = params.horizon
    for name, value in (("steps", steps), ("episodes", episodes)):
        if not isinstance(value, int) or isinstance(value, bool) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}")
    run = _compiled(policy, steps, episodes, deterministic)
    record = jax.device_get(run(policy.params, params, jax.random.PRNGKey(seed)))
    out = {name: np.swapaxes(np.asarray(value), 0, 1) for name, value in _flatten(record).items()}
    if not policy.recurrent:
        out.pop("hidden"), out.pop("cell")
    return out


def _compiled(policy: Any, steps: int, episodes: int, deterministic: bool) -> Any:
    """The jitted scan for these sizes, cached on the policy (one compilation per shape)."""
    cache = policy._rollout_cache
    if (steps, episodes, deterministic) not in cache:
        cache[steps, episodes, deterministic] = jax.jit(
            lambda acting, env_params, key: _scan(policy, acting, env_params, key, steps, episodes,
                                                  deterministic))
    return cache[steps, episodes, deterministic]


def _scan(policy: Any, acting: Any, env_params: Any, key: jax.Array, steps: int, episodes: int,
          deterministic: bool) -> dict[str, Any]:
    env, config = policy.env, policy.config
    reset_key, act_key, step_key = jax.random.split(key, 3)
    obs, env_state = jax.vmap(env.reset, in_axes=(0, None))(jax.random.split(reset_key, episodes), env_params)

    def step(loop: tuple, t: jax.Array) -> tuple[tuple, dict[str, Any]]:
        obs, env_state, carry = loop
        starts = jnp.full(episodes, t == 0)
        carry, mean, log_std, value = forward(policy.policy.network.apply, config, acting.params,
                                              acting.normalizer, carry, obs, starts)
        if not deterministic:
            mean = sample_batch(jax.random.split(jax.random.fold_in(act_key, t), episodes), mean, log_std)[0]
        action = policy.to_box(mean)
        keys = jax.random.split(jax.random.fold_in(step_key, t), episodes)
        out = jax.vmap(env.step, in_axes=(0, 0, 0, None))(keys, env_state, action, env_params)
        row = {"obs": obs, "state": env_state, "action": action, "value": value / config.reward_scale,
               "hidden": carry[1], "cell": carry[0], "reward": out.reward, "terminated": out.terminated,
               "truncated": out.truncated, "info": out.info}
        return (out.obs, out.state, carry), row

    loop = (obs, env_state, policy.policy.initial_carry(episodes))
    return jax.lax.scan(step, loop, jnp.arange(steps))[1]


def _flatten(record: dict[str, Any]) -> dict[str, Any]:
    """Nested state/info entries as flat ``state.xyz``-style keys."""
    flat = {}
    for name, value in record.items():
        if name in ("state", "info"):
            for path, leaf in jax.tree_util.tree_flatten_with_path(value)[0]:
                flat[name + "." + ".".join(_key_name(k) for k in path)] = leaf
        else:
            flat[name] = value
    return flat


def _key_name(key: Any) -> str:
    for attr in ("name", "key", "idx"):
        if hasattr(key, attr):
            return str(getattr(key, attr))
    return str(key)
