"""Acting with a trained PPO agent (evaluation, the CLI's eval-lorenz).

``policy.act(state_or_params, obs, carry, done, key, deterministic)`` takes any object with the two
fields acting needs, ``params`` (network parameters) and ``normalizer`` (observation statistics): a
:class:`RunnerState` (e.g. restored from a checkpoint) or a :class:`PolicyParams`. ``obs`` is (B, obs_dim)
raw, ``done`` (B,) marks observations that start an episode (the carry is reset there), ``carry`` comes
from ``initial_carry(B)`` or the previous call. Stochastic actions sample the Gaussian; deterministic
ones map its mean into the box (see distribution.py). ``act`` is pure: jit and vmap it freely.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxsimrl.agents.ppo import distribution
from jaxsimrl.agents.ppo.acting import forward, sample_batch
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.networks import Carry, initial_carry, make_network
from jaxsimrl.agents.ppo.normalizer import NormalizerState


@struct.dataclass
class PolicyParams:
    """The part of RunnerState that acting needs."""

    params: Any
    normalizer: NormalizerState


class Policy:
    """A stateless actor for ``config``'s network on ``env``'s action box."""

    def __init__(self, config: PPOConfig, env: Any, env_params: Any = None) -> None:
        self.config = config
        params = env.default_params() if env_params is None else env_params
        box = env.action_space(params)
        self.low, self.high = jnp.broadcast_to(box.low, box.shape), jnp.broadcast_to(box.high, box.shape)
        self.network = make_network(config, int(np.prod(box.shape)))

    def initial_carry(self, batch_size: int) -> Carry:
        return initial_carry(self.config, batch_size)

    def act(self, state_or_params: Any, obs: jax.Array, carry: Carry, done: jax.Array, key: jax.Array,
            deterministic: bool = True) -> tuple[jax.Array, Carry]:
        """Actions (B, action_dim) inside the box and the next carry."""
        carry, mean, log_std, _ = forward(self.network.apply, self.config, state_or_params.params,
                                          state_or_params.normalizer, carry, obs, done)
        u = mean if deterministic else sample_batch(jax.random.split(key, mean.shape[0]), mean, log_std)[0]
        return distribution.to_box(u, self.low, self.high, self.config.action_margin), carry


def make_policy(config: PPOConfig, env: Any = None, env_params: Any = None) -> Policy:
    """The policy of ``config`` on ``env`` (default: the Lorenz env with default params)."""
    if env is None:
        from jaxsimrl.envs.lorenz import Lorenz

        env = Lorenz()
    return Policy(config, env, env_params)
