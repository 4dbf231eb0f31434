"""The rollout of an asynchronous host batch (PPOConfig.async_envs, jaxsimrl.envs.host_async).

Each learner step acts on B = num_envs rows, but row ``r`` is env ``ids[r]`` of E = async_envs envs, a
different one from step to step: the batch returns whichever envs are ready (EnvPool's async mode,
Sample Factory, RLlib's APPO). The result an env returns completes the step it was *sent* at its
previous appearance, maybe several learner steps (or an update) earlier. So the rollout keeps a
**pending transition per env** (:class:`Pending`, E rows): the normalised observation, pre-squash
action, behaviour log-prob and value of its step in flight. At each step:

1. the rows acted on become the pending transitions of their envs, and the actions are sent;
2. each returned row completes its env's pending transition, with the returned reward, termination,
   truncation and ``V(final_obs)`` bootstrap (as in lock-step); a row whose env had none (its first
   appearance after the reset) completes nothing and is stored with weight 0.

The stored rollout is (chunks, seq_len, B) as in lock-step, with each row's weight and env id; GAE then
runs per env (losses.compute_gae_per_env), seeded with V of what each env observes after the rollout:
the learner's rows' values, or an env's pending value where its step is still in flight. Pending
transitions carry over to the next update with their behaviour log-prob, so the PPO ratio stays right
(policy lag stays within one update: the parameters are fixed during a rollout). MLP networks only
(PPOConfig validates it): a recurrent carry would have to follow each env's own steps.

``Transition.raw_obs`` holds the rows acted on (every observation the learner saw, once), for the
observation normaliser's statistics, as in lock-step; RunnerState.episode_return is unused (the
returns run per env, in :class:`AsyncEnvState`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from jaxsimrl.agents.ppo import distribution
from jaxsimrl.agents.ppo.acting import forward, observe, sample_batch
from jaxsimrl.agents.ppo.learner import time_flat
from jaxsimrl.agents.ppo.losses import compute_gae_per_env
from jaxsimrl.agents.ppo.rollout import (
    EpisodeStats,
    RolloutContext,
    RunnerState,
    Transition,
    bootstrap_value,
    local_keys,
)


class Pending(NamedTuple):
    """Each env's step in flight (leading axis: the E envs)."""

    obs: jax.Array  # normalised, as the network saw it
    starts: jax.Array
    u: jax.Array
    log_prob: jax.Array  # behaviour log-prob (the parameters of the update that sent it)
    value: jax.Array
    valid: jax.Array  # bool: the env has a step in flight


class AsyncEnvState(NamedTuple):
    """RunnerState.env_state of an asynchronous batch."""

    ids: jax.Array  # (B,) int32: the env of each row of RunnerState.obs
    pending: Pending
    episode_return: jax.Array  # (E,) undiscounted return of each env's running episode


def initial_env_state(ids: jax.Array, num_envs: int, obs_dim: int, action_dim: int) -> AsyncEnvState:
    """The state after a reset: the learner holds the envs ``ids``, no env has a step in flight."""
    zeros = jnp.zeros(num_envs, jnp.float32)
    pending = Pending(jnp.zeros((num_envs, obs_dim), jnp.float32), jnp.zeros(num_envs, bool),
                      jnp.zeros((num_envs, action_dim), jnp.float32), zeros, zeros, jnp.zeros(num_envs, bool))
    return AsyncEnvState(jnp.asarray(ids, jnp.int32), pending, zeros)


def async_env_step(ctx: RolloutContext, runner: RunnerState, key: jax.Array
                   ) -> tuple[RunnerState, Transition, EpisodeStats]:
    """One learner step (rollout.collect's ``env_step``): act on the B rows, send, and turn the returned
    rows into the transitions they complete (see the module docstring)."""
    act_key, step_key, reset_key = jax.random.split(key, 3)
    env: AsyncEnvState = runner.env_state
    obs = observe(ctx.config, runner.normalizer, runner.obs)
    carry, mean, log_std, value = forward(ctx.apply_fn, ctx.config, runner.params, runner.normalizer,
                                          runner.carry, runner.obs, runner.starts)
    u, log_prob = sample_batch(local_keys(ctx, act_key), mean, log_std)
    sent = _set_rows(env.pending, env.ids, Pending(obs, runner.starts, u, log_prob, value,
                                                   jnp.ones_like(runner.starts)))
    env_keys = jnp.stack([local_keys(ctx, step_key), local_keys(ctx, reset_key)], axis=1)  # unused by hosts
    action = distribution.to_box(u, ctx.low, ctx.high, ctx.config.action_margin)
    step = ctx.vec.step(env_keys, env.ids, action)
    ids = step.state
    done = step.terminated | step.truncated
    completed = jax.tree.map(lambda x: x[ids], sent)
    real = completed.valid
    transition = Transition(completed.obs, runner.obs, completed.starts, completed.u, completed.log_prob,
                            completed.value, step.reward * ctx.config.reward_scale, step.terminated,
                            step.truncated, bootstrap_value(ctx, runner, carry, step),
                            real.astype(jnp.float32), ids)

    returns = env.episode_return[ids] + jnp.where(real, step.reward, 0.0)
    ended = step.ended & real
    stats = EpisodeStats(jnp.sum(jnp.where(ended, returns, 0.0)), jnp.sum(ended.astype(jnp.float32)))
    pending = sent._replace(valid=sent.valid.at[ids].set(False))  # their results are with the learner
    env = AsyncEnvState(ids, pending, env.episode_return.at[ids].set(jnp.where(done, 0.0, returns)))
    runner = runner.replace(env_state=env, obs=step.obs, starts=done | ~real, carry=carry)
    return runner, transition, stats


def _set_rows(table: Pending, ids: jax.Array, rows: Pending) -> Pending:
    """``table`` with its entries ``ids`` (distinct) replaced by ``rows``."""
    return jax.tree.map(lambda whole, part: whole.at[ids].set(part.astype(whole.dtype)), table, rows)


def async_advantages(config: Any, transitions: Transition, env: AsyncEnvState, last_value: jax.Array
                     ) -> tuple[jax.Array, jax.Array]:
    """Per-env GAE of an asynchronous rollout, shaped (T, B) as lock-step's; ``env`` is the state after
    the rollout and ``last_value`` V of its rows (RunnerState.obs)."""
    seeds = jnp.where(env.pending.valid, env.pending.value, 0.0).at[env.ids].set(last_value)
    flat = time_flat
    return compute_gae_per_env(
        flat(transitions.reward), flat(transitions.value), flat(transitions.terminated),
        flat(transitions.truncated), flat(transitions.final_value), flat(transitions.weight),
        flat(transitions.env_id), seeds, config.gamma, config.gae_lambda)
