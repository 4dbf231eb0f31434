"""Running observation mean/variance (parallel Welford merge), exact across devices.

The statistics are a pytree in the learner state. A batch is summarised as (count, mean, M2) and merged
with Chan et al.'s parallel formula; under ``shard_map`` the per-device batches are first combined with
``psum`` (counts, count-weighted means, then M2 about the global mean), so N devices holding parts of a
batch produce the same statistics as one device holding all of it.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

_EPS = 1e-8


@struct.dataclass
class NormalizerState:
    count: jax.Array  # scalar float32: observations seen
    mean: jax.Array  # (obs_dim,)
    m2: jax.Array  # (obs_dim,): sum of squared deviations from the mean


def init_normalizer(obs_dim: int) -> NormalizerState:
    """Empty statistics: normalisation is the identity until data arrives."""
    return NormalizerState(count=jnp.float32(0.0), mean=jnp.zeros(obs_dim, jnp.float32),
                           m2=jnp.zeros(obs_dim, jnp.float32))


def batch_stats(obs: jax.Array, axis_name: str | None = None) -> NormalizerState:
    """Statistics of ``obs`` (..., obs_dim); with ``axis_name``, of the union of all devices' batches."""
    flat = obs.reshape(-1, obs.shape[-1]).astype(jnp.float32)
    count = jnp.float32(flat.shape[0])
    total = flat.sum(axis=0)
    if axis_name is not None:
        count = jax.lax.psum(count, axis_name)
        total = jax.lax.psum(total, axis_name)
    mean = total / count
    m2 = jnp.sum(jnp.square(flat - mean), axis=0)
    if axis_name is not None:
        m2 = jax.lax.psum(m2, axis_name)
    return NormalizerState(count=count, mean=mean, m2=m2)


def merge(a: NormalizerState, b: NormalizerState) -> NormalizerState:
    """Chan et al.'s parallel combination of two summaries."""
    count = a.count + b.count
    safe = jnp.maximum(count, 1.0)
    delta = b.mean - a.mean
    mean = a.mean + delta * (b.count / safe)
    m2 = a.m2 + b.m2 + jnp.square(delta) * (a.count * b.count / safe)
    return NormalizerState(count=count, mean=mean, m2=m2)


def update(state: NormalizerState, obs: jax.Array, axis_name: str | None = None) -> NormalizerState:
    """Fold a batch of observations into the running statistics."""
    return merge(state, batch_stats(obs, axis_name))


def normalize(state: NormalizerState, obs: jax.Array, clip: float, std_floor: float = 0.0) -> jax.Array:
    """(obs - mean) / max(std, std_floor), clipped to +-clip; the identity while no data has been seen."""
    var = state.m2 / jnp.maximum(state.count, 1.0)
    seen = state.count > 0
    mean = jnp.where(seen, state.mean, 0.0)
    std = jnp.where(seen, jnp.maximum(jnp.sqrt(var + _EPS), std_floor), 1.0)
    return jnp.clip((obs - mean) / std, -clip, clip)
