"""The policy's action distribution in the env's own action units.

The network gives a diagonal Gaussian over an unbounded ``u`` (``loc``, ``scale``); the env gets
``a = low + (tanh(u) + 1) / 2 (high - low)`` (see jaxsimrl.agents.ppo.distribution). Since the map is
monotone per component, ``to_box(loc)`` is each component's median: the action that
``act(deterministic=True)`` takes. ``log_prob`` is the density of ``a`` itself, change of variables
included, so it integrates to one over the box. With an action margin (PPOConfig.action_margin) the
tanh maps onto the widened box and actions are clipped into [low, high]: the bounds carry point masses,
and ``log_prob`` is the density of the actions strictly inside.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
from flax import struct

from jaxsimrl.agents.ppo import distribution

_EDGE = 1e-6  # actions on the box's edge are pulled this far inside (tanh never reaches +-1)


@struct.dataclass
class ActionDistribution:
    """A batch (..., A) of squashed Gaussians on the box [low, high]."""

    loc: jax.Array  # (..., A) pre-squash Gaussian mean
    scale: jax.Array  # (..., A) pre-squash Gaussian standard deviation
    low: jax.Array  # (A,)
    high: jax.Array  # (A,)
    margin: float = struct.field(pytree_node=False, default=0.0)  # PPOConfig.action_margin

    @property
    def median(self) -> jax.Array:
        """The deterministic action (per-component median), in env units."""
        return distribution.to_box(self.loc, self.low, self.high, self.margin)

    def sample(self, key: jax.Array, shape: tuple[int, ...] = ()) -> jax.Array:
        """Actions of shape ``shape + loc.shape``, in env units."""
        return _sample(self, key, tuple(shape))

    def log_prob(self, action: jax.Array) -> jax.Array:
        """log density of ``action`` (..., A) in env units, summed over components."""
        return _log_prob(self, jnp.asarray(action, jnp.float32))

    def mean_and_std(self, key: jax.Array, samples: int = 4096) -> tuple[jax.Array, jax.Array]:
        """Monte Carlo mean and standard deviation of the action in env units (no closed form)."""
        draws = self.sample(key, (samples,))
        return draws.mean(axis=0), draws.std(axis=0)


@functools.partial(jax.jit, static_argnums=2)
def _sample(dist: ActionDistribution, key: jax.Array, shape: tuple[int, ...]) -> jax.Array:
    u = dist.loc + dist.scale * jax.random.normal(key, shape + dist.loc.shape)
    return distribution.to_box(u, dist.low, dist.high, dist.margin)


@jax.jit
def _log_prob(dist: ActionDistribution, action: jax.Array) -> jax.Array:
    low, high = distribution.widened(dist.low, dist.high, dist.margin)
    half = 0.5 * (high - low)
    y = jnp.clip((action - low) / half - 1.0, -1.0 + _EDGE, 1.0 - _EDGE)
    gaussian = jax.scipy.stats.norm.logpdf(jnp.arctanh(y), dist.loc, dist.scale)
    return jnp.sum(gaussian - jnp.log1p(-jnp.square(y)) - jnp.log(half), axis=-1)
