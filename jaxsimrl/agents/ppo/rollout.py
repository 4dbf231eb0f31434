"""Collect one update's worth of experience from this device's envs (a ``lax.scan`` over steps).

The scan is nested: an outer scan over the ``chunks_per_env`` training sequences and an inner one over
the ``seq_len`` steps of each, so the recurrent carry at the start of every chunk is stored without
keeping the carry of every step. The envs sit behind a :class:`jaxsimrl.envs.vec.VecEnv`, which
auto-resets them: after a step whose episode ended (terminated or truncated) the next observation is
the first of a new episode and is flagged as an episode start (the network zeroes the carry there).
For a step that was truncated (and not terminated) the critic is evaluated on the step's final
(pre-reset) observation, ``final_obs``, and stored for the GAE bootstrap (see losses.py).

An asynchronous host batch (PPOConfig.async_envs) runs the same scans with another step function
(rollout_async.py), whose rows belong to a different env from step to step.

Random numbers are drawn per *global* env index and sliced to this device's envs, so sharding the envs
over devices does not change any sample.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
from flax import struct

from jaxsimrl.agents.ppo import distribution
from jaxsimrl.agents.ppo.acting import forward, observe, sample_batch
from jaxsimrl.agents.ppo.normalizer import NormalizerState


@struct.dataclass
class RunnerState:
    """The whole learner + actor state: a pytree of arrays only (orbax-saveable).

    ``params``, ``opt_state``, ``normalizer``, ``rng`` and ``update_step`` are replicated over devices;
    ``env_state``, ``obs``, ``starts``, ``carry`` and ``episode_return`` have a leading env axis
    (num_envs), sharded over devices.
    """

    params: Any
    opt_state: Any
    normalizer: NormalizerState
    env_state: Any
    obs: jax.Array  # (num_envs, obs_dim) raw observation the next step acts on
    starts: jax.Array  # (num_envs,) bool: obs is the first observation of an episode
    carry: Any  # recurrent state (num_envs, H) pair
    episode_return: jax.Array  # (num_envs,) undiscounted return of the running episodes
    rng: jax.Array  # raw uint32 PRNG key
    update_step: jax.Array  # int32: updates done so far


class Transition(NamedTuple):
    """One step of every local env (arrays with a leading env axis)."""

    obs: jax.Array  # normalised, as the network saw it
    raw_obs: jax.Array  # for the normaliser statistics
    starts: jax.Array
    u: jax.Array
    log_prob: jax.Array
    value: jax.Array
    reward: jax.Array  # scaled by config.reward_scale
    terminated: jax.Array
    truncated: jax.Array
    final_value: jax.Array  # V(pre-reset final obs) where truncated, else 0
    # Asynchronous batch only (rollout_async.py; None in lock-step): 0 for a row that completes no
    # transition, else 1, and the env each row belongs to.
    weight: jax.Array | None = None
    env_id: jax.Array | None = None


class EpisodeStats(NamedTuple):
    return_sum: jax.Array  # summed returns of the episodes completed in this rollout (local envs)
    count: jax.Array


class RolloutContext(NamedTuple):
    """What the rollout needs besides the state (static per trainer)."""

    apply_fn: Any
    vec: Any  # jaxsimrl.envs.vec.VecEnv
    config: Any
    low: jax.Array
    high: jax.Array
    num_local_envs: int
    axis_name: str | None


#: One step of every local env: (ctx, runner, key) -> (runner, transition, episode stats).
EnvStep = Callable[[RolloutContext, RunnerState, jax.Array], tuple[RunnerState, Transition, EpisodeStats]]


def local_slice(ctx: RolloutContext, global_array: jax.Array) -> jax.Array:
    """The rows of a per-global-env array that belong to this device."""
    if ctx.axis_name is None:
        return global_array
    start = jax.lax.axis_index(ctx.axis_name) * ctx.num_local_envs
    return jax.lax.dynamic_slice_in_dim(global_array, start, ctx.num_local_envs, axis=0)


def local_keys(ctx: RolloutContext, key: jax.Array) -> jax.Array:
    """One key per local env, drawn from the keys of all global envs."""
    return local_slice(ctx, jax.random.split(key, ctx.config.num_envs))


def _env_step(ctx: RolloutContext, runner: RunnerState, key: jax.Array
              ) -> tuple[RunnerState, Transition, EpisodeStats]:
    act_key, step_key, reset_key = jax.random.split(key, 3)
    obs = observe(ctx.config, runner.normalizer, runner.obs)  # stored: the update replays what was seen
    carry, mean, log_std, value = forward(ctx.apply_fn, ctx.config, runner.params, runner.normalizer,
                                          runner.carry, runner.obs, runner.starts)
    u, log_prob = sample_batch(local_keys(ctx, act_key), mean, log_std)
    action = distribution.to_box(u, ctx.low, ctx.high, ctx.config.action_margin)
    env_keys = jnp.stack([local_keys(ctx, step_key), local_keys(ctx, reset_key)], axis=1)
    step = ctx.vec.step(env_keys, runner.env_state, action)
    done = step.terminated | step.truncated
    transition = Transition(obs, runner.obs, runner.starts, u, log_prob, value,
                            step.reward * ctx.config.reward_scale, step.terminated, step.truncated,
                            bootstrap_value(ctx, runner, carry, step))

    episode_return = runner.episode_return + step.reward
    stats = EpisodeStats(jnp.sum(jnp.where(step.ended, episode_return, 0.0)),
                         jnp.sum(step.ended.astype(jnp.float32)))
    runner = runner.replace(env_state=step.state, obs=step.obs, starts=done, carry=carry,
                            episode_return=jnp.where(done, 0.0, episode_return))
    return runner, transition, stats


def collect(ctx: RolloutContext, runner: RunnerState, key: jax.Array, env_step: EnvStep | None = None
            ) -> tuple[RunnerState, Transition, Any, EpisodeStats]:
    """Run ``steps_per_env`` steps in every local env (``env_step``: one step of the batch; default
    the lock-step one, an asynchronous batch passes rollout_async.async_env_step).

    Returns the advanced state, the transitions shaped (chunks, seq_len, local envs, ...), the carry at
    the start of each chunk (chunks, local envs, ...) and the completed-episode statistics.
    """
    cfg = ctx.config
    env_step = _env_step if env_step is None else env_step

    def chunk(runner: RunnerState, chunk_index: jax.Array) -> tuple[RunnerState, tuple]:
        def step(inner: tuple[RunnerState, EpisodeStats], t: jax.Array) -> tuple[tuple, Transition]:
            runner, stats = inner
            runner, transition, new = env_step(ctx, runner, jax.random.fold_in(key, t))
            stats = EpisodeStats(stats.return_sum + new.return_sum, stats.count + new.count)
            return (runner, stats), transition

        start_carry = runner.carry
        times = chunk_index * cfg.seq_len + jnp.arange(cfg.seq_len)
        zero = EpisodeStats(jnp.float32(0.0), jnp.float32(0.0))
        (runner, stats), transitions = jax.lax.scan(step, (runner, zero), times)
        return runner, (transitions, start_carry, stats)

    runner, (transitions, carries, stats) = jax.lax.scan(chunk, runner, jnp.arange(cfg.chunks_per_env))
    return runner, transitions, carries, jax.tree.map(jnp.sum, stats)


def critic_value(ctx: RolloutContext, params: Any, normalizer: NormalizerState, carry: Any,
                 raw_obs: jax.Array, starts: jax.Array) -> jax.Array:
    """V(raw_obs) of every local env: one network step from ``carry`` (the carry it leaves is dropped)."""
    return forward(ctx.apply_fn, ctx.config, params, normalizer, carry, raw_obs, starts)[3]


def bootstrap_value(ctx: RolloutContext, runner: RunnerState, carry: Any, step: Any) -> jax.Array:
    """V(final obs) of the steps that were truncated and not terminated; zeros when there is none."""
    bootstrap = step.truncated & ~step.terminated

    def value_of_final_obs() -> jax.Array:
        value = critic_value(ctx, runner.params, runner.normalizer, carry, step.final_obs,
                             jnp.zeros_like(runner.starts))
        return jnp.where(bootstrap, value, 0.0)

    # under shard_map this stays a real branch: the extra forward pass runs only when needed
    return jax.lax.cond(jnp.any(bootstrap), value_of_final_obs,
                        lambda: jnp.zeros(step.reward.shape, jnp.float32))
