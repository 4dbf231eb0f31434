"""GAE(lambda) and the PPO clipped-surrogate loss.

Bootstrapping: after a step that *terminated* its episode the next value is 0 (also when the same
step hit a time cap: the task's end wins); after a step that was only *truncated* it is
``final_values[t]``, the critic's value of the episode's last real observation (the rollout evaluates
it on the pre-reset observation); otherwise it is ``values[t + 1]`` (``last_value`` after
the final step). The GAE recursion is cut at every episode end.

An asynchronous batch (PPOConfig.async_envs) has no env per column: :func:`compute_gae_per_env` follows
each row's env id instead, and rows of weight 0 (no transition) are ignored by GAE and by the loss.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import jax
import jax.numpy as jnp

from jaxsimrl.agents.ppo.distribution import gaussian, squashed_entropy, widened


def compute_gae(rewards: jax.Array, values: jax.Array, terminated: jax.Array, truncated: jax.Array,
                final_values: jax.Array, last_value: jax.Array, gamma: float, gae_lambda: float
                ) -> tuple[jax.Array, jax.Array]:
    """Advantages and value targets for time-major (T, ...) arrays.

    ``values[t]`` = V(obs_t); ``final_values[t]`` = V(final obs of step t), used only where
    ``truncated[t] & ~terminated[t]``; ``last_value`` = V(obs after the last step).
    Returns (advantages, advantages + values).
    """
    next_values = jnp.concatenate([values[1:], last_value[None]], axis=0)
    next_values = jnp.where(terminated, 0.0, jnp.where(truncated, final_values, next_values))
    not_done = 1.0 - (terminated | truncated).astype(values.dtype)
    deltas = rewards + gamma * next_values - values

    def backward(carry: jax.Array, xs: tuple[jax.Array, jax.Array]) -> tuple[jax.Array, jax.Array]:
        delta, nd = xs
        adv = delta + gamma * gae_lambda * nd * carry
        return adv, adv

    _, advantages = jax.lax.scan(backward, jnp.zeros_like(last_value), (deltas, not_done), reverse=True)
    return advantages, advantages + values


def compute_gae_per_env(rewards: jax.Array, values: jax.Array, terminated: jax.Array, truncated: jax.Array,
                        final_values: jax.Array, weights: jax.Array, env_ids: jax.Array,
                        next_values: jax.Array, gamma: float, gae_lambda: float
                        ) -> tuple[jax.Array, jax.Array]:
    """:func:`compute_gae` for time-major (T, B) rows that belong to envs ``env_ids`` (distinct within a
    step), in each env's own order: a reverse scan whose carry (next value, next advantage) has one
    entry per env, seeded with ``next_values`` (E,), V of what each env observes after the rollout.
    Bootstrapping as compute_gae's. Rows of weight 0 get advantage 0 and leave their env's carry alone.
    Returns (advantages, advantages + values)."""
    def backward(carry: tuple[jax.Array, jax.Array], row: tuple) -> tuple[tuple, jax.Array]:
        next_value, next_adv = carry
        reward, value, term, trunc, final_value, weight, ids = row
        following = jnp.where(term, 0.0, jnp.where(trunc, final_value, next_value[ids]))
        not_done = 1.0 - (term | trunc).astype(value.dtype)
        adv = reward + gamma * following - value + gamma * gae_lambda * not_done * next_adv[ids]
        real = weight > 0
        adv = jnp.where(real, adv, 0.0)
        carry = (next_value.at[ids].set(jnp.where(real, value, next_value[ids])),
                 next_adv.at[ids].set(jnp.where(real, adv, next_adv[ids])))
        return carry, adv

    rows = (rewards, values, terminated, truncated, final_values, weights, env_ids)
    _, advantages = jax.lax.scan(backward, (next_values, jnp.zeros_like(next_values)), rows, reverse=True)
    return advantages, advantages + values


class Batch(NamedTuple):
    """One minibatch of training sequences, time-major (seq_len, B, ...)."""

    obs: jax.Array  # normalised observations
    starts: jax.Array  # episode-start flags (carry reset before the step)
    u: jax.Array  # pre-squash actions
    log_prob: jax.Array
    value: jax.Array
    advantage: jax.Array
    target: jax.Array
    carry: Any  # recurrent carry at the first step of each sequence, (B, ...)
    weight: jax.Array | None = None  # asynchronous batch: 0 where a row holds no transition


def _mean(x: jax.Array, weight: jax.Array | None) -> jax.Array:
    """The mean of ``x``; with ``weight``, over the rows of weight > 0 (weights broadcast over x)."""
    if weight is None:
        return jnp.mean(x)
    return jnp.sum(x * weight) / jnp.maximum(jnp.sum(weight), 1.0)


def global_mean(x: jax.Array, axis_name: str | None, weight: jax.Array | None = None) -> jax.Array:
    """Mean over the global batch; exact because every device holds an equal-size part (weighted:
    per device; an asynchronous batch runs on one device)."""
    m = _mean(x, weight)
    return m if axis_name is None else jax.lax.pmean(m, axis_name)


def normalize_advantages(adv: jax.Array, axis_name: str | None, weight: jax.Array | None = None
                         ) -> jax.Array:
    """Standardise over the global minibatch (over its rows of weight > 0, if weighted)."""
    mean = global_mean(adv, axis_name, weight)
    var = global_mean(jnp.square(adv - mean), axis_name, weight)
    return (adv - mean) / (jnp.sqrt(var) + 1e-8)


def ppo_loss(params: Any, apply_fn: Any, batch: Batch, config: Any, low: jax.Array, high: jax.Array
             ) -> tuple[jax.Array, dict[str, jax.Array]]:
    """Clipped surrogate + value loss - entropy bonus, averaged over this device's part of the batch.

    The entropy is that of the squashed action in the box [low, high], widened by the config's
    action_margin (see distribution.py).

    No collectives in here on purpose: the caller averages gradients and metrics across devices
    (pmean of equal-size local means = the global mean), and standardises advantages beforehand.
    Rows of ``batch.weight`` 0 (an asynchronous batch's non-transitions) count in no mean.
    """
    weight = batch.weight
    _, mean, log_std, value = apply_fn(params, batch.carry, batch.obs, batch.starts)
    dist = gaussian(mean, log_std)
    log_prob = dist.log_prob(batch.u)
    log_ratio = log_prob - batch.log_prob
    ratio = jnp.exp(log_ratio)
    adv = batch.advantage
    surrogate = jnp.minimum(ratio * adv, jnp.clip(ratio, 1 - config.clip_eps, 1 + config.clip_eps) * adv)
    policy_loss = -_mean(surrogate, weight)

    value_err = jnp.square(value - batch.target)
    if config.clip_value:
        clipped = batch.value + jnp.clip(value - batch.value, -config.clip_eps, config.clip_eps)
        value_err = jnp.maximum(value_err, jnp.square(clipped - batch.target))
    value_loss = 0.5 * _mean(value_err, weight)
    entropy = _mean(squashed_entropy(mean, log_std, *widened(low, high, config.action_margin)), weight)
    total = policy_loss + config.vf_coef * value_loss - config.ent_coef * entropy
    metrics = {
        "policy_loss": policy_loss,
        "value_loss": value_loss,
        "entropy": entropy,
        "approx_kl": _mean((ratio - 1) - log_ratio, weight),
        "clip_fraction": _mean((jnp.abs(ratio - 1) > config.clip_eps).astype(jnp.float32), weight),
    }
    return total, metrics
