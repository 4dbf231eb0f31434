"""The Gaussian policy and its bounded mapping to the env's action box.

The network outputs a mean ``mu`` and a log-std for an *unbounded* diagonal Gaussian. A rollout
samples ``u ~ N(mu, sigma)`` and sends the env

    action = low + (tanh(u) + 1) / 2 * (high - low),

which always lies inside the box [low, high] (tanh(u) is in (-1, 1); float rounding can only reach the
edges). The rollout stores ``u`` and ``log N(u; mu, sigma)``, and the PPO update recomputes
``log N(u; mu', sigma')`` for the same ``u``. The exact log-density of the squashed action would add
``-sum log|d action / d u|``, a term that depends only on ``u``, not on the parameters; it cancels in the
ratio pi'(a)/pi(a), so PPO's ratio, KL estimate and clipping are exactly those of the squashed policy.
The entropy bonus uses the Gaussian's entropy (the squashed policy's entropy has no closed form).
The deterministic action is the mean ``mu`` mapped through the same function.
"""

from __future__ import annotations

import distrax
import jax
import jax.numpy as jnp


def gaussian(mean: jax.Array, log_std: jax.Array) -> distrax.MultivariateNormalDiag:
    """The pre-squash policy distribution (log_std broadcasts against mean)."""
    return distrax.MultivariateNormalDiag(mean, jnp.broadcast_to(jnp.exp(log_std), mean.shape))


def to_box(u: jax.Array, low: jax.Array, high: jax.Array) -> jax.Array:
    """Map an unbounded pre-squash sample into the action box [low, high]."""
    return low + (jnp.tanh(u) + 1.0) * 0.5 * (high - low)


def sample(key: jax.Array, mean: jax.Array, log_std: jax.Array) -> tuple[jax.Array, jax.Array]:
    """Sample the pre-squash ``u`` and return it with its Gaussian log-probability."""
    return gaussian(mean, log_std).sample_and_log_prob(seed=key)
