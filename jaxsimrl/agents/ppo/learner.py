"""One PPO update on a collected rollout: GAE (lock-step: :func:`gae`; an asynchronous batch's per
env: rollout_async.py), then epochs x minibatches of Adam steps.

Minibatches are "all local envs x a subset of the training sequences (chunks)": the chunk order is
shuffled with a key every device shares, so the global minibatch is the union of the devices' local
ones, every local part has the same size, and ``pmean`` of the local gradients is the gradient of the
global minibatch mean. That makes N devices learn exactly what one device learns with the same total
batch (up to float summation order).
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import optax

from jaxsimrl.agents.ppo.losses import Batch, compute_gae, normalize_advantages, ppo_loss
from jaxsimrl.agents.ppo.rollout import RolloutContext, Transition


def make_optimizer(config: Any, num_updates: int) -> tuple[optax.GradientTransformation, optax.Schedule]:
    """Adam with global-norm gradient clipping; the learning rate optionally anneals linearly to 0
    (from ``config.anneal_start_update``, see PPOConfig.learning_rate; the schedule counts SGD steps)."""
    per_update = config.update_epochs * config.num_minibatches
    if config.anneal_lr:
        start = config.lr if config.anneal_start_lr is None else config.anneal_start_lr
        begin = config.anneal_start_update * per_update
        schedule = optax.linear_schedule(start, 0.0, max(num_updates * per_update - begin, 1), begin)
    else:
        schedule = optax.constant_schedule(config.lr)
    tx = optax.chain(optax.clip_by_global_norm(config.max_grad_norm), optax.adam(schedule, eps=1e-5))
    return tx, schedule


def _time_major(x: jax.Array) -> jax.Array:
    """(chunks, seq_len, envs, ...) -> (seq_len, chunks * envs, ...)."""
    x = jnp.swapaxes(x, 0, 1)
    return x.reshape(x.shape[:1] + (-1,) + x.shape[3:])


def _minibatch(data: Batch, chunk_ids: jax.Array) -> Batch:
    """The sequences of the chosen chunks from every local env, time-major."""
    seqs = jax.tree.map(lambda x: _time_major(x[chunk_ids]), data._replace(carry=None))
    carry = jax.tree.map(lambda c: c[chunk_ids].reshape((-1,) + c.shape[2:]), data.carry)
    return seqs._replace(carry=carry)


def time_flat(x: jax.Array) -> jax.Array:
    """(chunks, seq_len, ...) -> (chunks * seq_len, ...): the rollout's steps in order."""
    return x.reshape((x.shape[0] * x.shape[1],) + x.shape[2:])


def gae(ctx: RolloutContext, transitions: Transition, last_value: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Advantages and value targets of a lock-step rollout, shaped (T, local envs) (T = chunks x seq_len)."""
    cfg, flat = ctx.config, time_flat
    return compute_gae(
        flat(transitions.reward), flat(transitions.value), flat(transitions.terminated),
        flat(transitions.truncated), flat(transitions.final_value), last_value, cfg.gamma, cfg.gae_lambda)


def learn(ctx: RolloutContext, tx: optax.GradientTransformation, params: Any, opt_state: Any,
          transitions: Transition, carries: Any, advantages: jax.Array, targets: jax.Array, key: jax.Array
          ) -> tuple[Any, Any, dict[str, jax.Array]]:
    """update_epochs x num_minibatches gradient steps on the rollout and its advantages and targets
    (T, local envs); returns params, opt_state, mean metrics. Rows of ``transitions.weight`` 0 (an
    asynchronous batch's) count in no loss."""
    cfg = ctx.config
    chunks, seq_len = transitions.reward.shape[:2]
    unflat = lambda x: x.reshape((chunks, seq_len) + x.shape[1:])  # noqa: E731
    data = Batch(transitions.obs, transitions.starts, transitions.u, transitions.log_prob, transitions.value,
                 unflat(advantages), unflat(targets), carries, transitions.weight)
    grad_fn = jax.grad(ppo_loss, has_aux=True)

    def sgd_step(train: tuple[Any, Any], chunk_ids: jax.Array) -> tuple[tuple[Any, Any], dict]:
        params, opt_state = train
        batch = _minibatch(data, chunk_ids)
        if cfg.normalize_advantages:
            batch = batch._replace(advantage=normalize_advantages(batch.advantage, ctx.axis_name,
                                                                  batch.weight))
        grads, metrics = grad_fn(params, ctx.apply_fn, batch, cfg, ctx.low, ctx.high)
        if ctx.axis_name is not None:
            grads, metrics = jax.lax.pmean((grads, metrics), ctx.axis_name)
        updates, opt_state = tx.update(grads, opt_state, params)
        return (optax.apply_updates(params, updates), opt_state), metrics

    def epoch(train: tuple[Any, Any], epoch_key: jax.Array) -> tuple[tuple[Any, Any], dict]:
        order = jax.random.permutation(epoch_key, chunks).reshape(cfg.num_minibatches, -1)
        return jax.lax.scan(sgd_step, train, order)

    (params, opt_state), metrics = jax.lax.scan(epoch, (params, opt_state),
                                                jax.random.split(key, cfg.update_epochs))
    return params, opt_state, jax.tree.map(jnp.mean, metrics)
