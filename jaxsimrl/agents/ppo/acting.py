"""The network's one forward step on raw observations: what the trainer's rollout and every acting
API (:class:`jaxsimrl.agents.ppo.policy.Policy`, :func:`jaxsimrl.load_policy`) share.

``forward`` normalises the raw observations as training does (``observe``) and runs the actor-critic
for one time step from ``carry``; ``sample_batch`` draws one pre-squash action per env. Keeping these in
one place means an action taken while training and one taken from a loaded checkpoint go through the
same code.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax

from jaxsimrl.agents.ppo import distribution
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.normalizer import NormalizerState, normalize

# apply_fn(params, carry, obs (T, B, obs_dim), starts (T, B)) -> (carry, mean, log_std, value)
ApplyFn = Callable[..., tuple[Any, jax.Array, jax.Array, jax.Array]]


def observe(config: PPOConfig, normalizer: NormalizerState, obs: jax.Array) -> jax.Array:
    """What the network sees, in training and when acting: the (optionally) normalised observation."""
    if not config.normalize_obs:
        return obs
    return normalize(normalizer, obs, config.obs_clip, config.obs_std_floor)


def forward(apply_fn: ApplyFn, config: PPOConfig, params: Any, normalizer: NormalizerState, carry: Any,
            raw_obs: jax.Array, starts: jax.Array) -> tuple[Any, jax.Array, jax.Array, jax.Array]:
    """One network step for a batch: raw_obs (B, obs_dim), starts (B,) (True resets the carry there).

    Returns (next carry, pre-squash mean (B, A), log_std (A,), value (B,)); the value is in the
    critic's units, i.e. of rewards scaled by ``config.reward_scale``.
    """
    obs = observe(config, normalizer, raw_obs)
    carry, mean, log_std, value = apply_fn(params, carry, obs[None], starts[None])
    return carry, mean[0], log_std, value[0]


def sample_batch(keys: jax.Array, mean: jax.Array, log_std: jax.Array) -> tuple[jax.Array, jax.Array]:
    """One pre-squash sample per row of ``mean`` (B, A), with key ``keys[i]``; returns (u, log N(u))."""
    return jax.vmap(distribution.sample, in_axes=(0, 0, None))(keys, mean, log_std)
