"""Acting with a trained PPO agent: the one inference function every caller goes through.

``policy.act(state_or_params, obs, carry, done, key, deterministic)`` takes any object with the two
fields acting needs, ``params`` (network parameters) and ``normalizer`` (observation statistics): a
:class:`RunnerState` (e.g. restored from a checkpoint) or a :class:`PolicyParams`. ``obs`` is (B, obs_dim)
raw, ``done`` (B,) marks observations that start an episode (the carry is reset there), ``carry`` comes
from ``initial_carry(B)`` or the previous call. Stochastic actions sample the Gaussian, one key per row
split from ``key``; deterministic ones map its mean into the box (see distribution.py). ``act`` is pure:
jit and vmap it freely. The trainer, ``jaxsimrl.load_policy``, eval-foam's batched actor and solve all
act through it (or through :meth:`Policy.forward` where they also want the value).

A policy needs of its env only the action box, so it is built on an :class:`ActionBox`; an env (anything
with ``action_space(params)``) is still accepted and reduced to its box.
"""

from __future__ import annotations

from typing import Any, NamedTuple

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


class ActionBox(NamedTuple):
    """The bounds [low, high] of an env's actions, each of the action's shape."""

    low: jax.Array
    high: jax.Array

    @classmethod
    def of(cls, space: Any) -> ActionBox:
        """The box of a gymnax/gymnasium-style space (``low``, ``high``, ``shape``)."""
        return cls(jnp.broadcast_to(space.low, space.shape), jnp.broadcast_to(space.high, space.shape))

    @classmethod
    def of_env(cls, env: Any, env_params: Any = None) -> ActionBox:
        """The box of ``env``'s action space under ``env_params`` (default: its default params)."""
        return cls.of(env.action_space(env.default_params() if env_params is None else env_params))


class Policy:
    """A stateless actor for ``config``'s network on an action box (an :class:`ActionBox`, or an env
    whose box under ``env_params`` is used)."""

    def __init__(self, config: PPOConfig, box: Any, env_params: Any = None) -> None:
        self.config = config
        self.box = box if isinstance(box, ActionBox) else ActionBox.of_env(box, env_params)
        self.low, self.high = self.box
        size = int(np.prod(self.low.shape))
        init_mean = None
        if config.init_action is not None:
            if len(config.init_action) != size:
                raise ValueError(f"init_action: expected {size} entries (one per action), got "
                                 f"{list(config.init_action)}")
            wanted = np.asarray(config.init_action, np.float64)
            init_mean = distribution.from_box(wanted, np.asarray(self.low), np.asarray(self.high),
                                              config.action_margin)
        self.network = make_network(config, size, init_mean)

    def initial_carry(self, batch_size: int) -> Carry:
        return initial_carry(self.config, batch_size)

    def forward(self, state_or_params: Any, obs: jax.Array, carry: Carry, starts: jax.Array
                ) -> tuple[Carry, jax.Array, jax.Array, jax.Array]:
        """(next carry, pre-squash mean (B, A), log_std (A,), value (B,) in the critic's units)."""
        return forward(self.network.apply, self.config, state_or_params.params, state_or_params.normalizer,
                       carry, obs, starts)

    def to_box(self, u: jax.Array) -> jax.Array:
        """The action in the box for pre-squash ``u``, mapped as in training."""
        return distribution.to_box(u, self.low, self.high, self.config.action_margin)

    def act(self, state_or_params: Any, obs: jax.Array, carry: Carry, done: jax.Array, key: jax.Array,
            deterministic: bool = True) -> tuple[jax.Array, Carry]:
        """Actions (B, action_dim) inside the box and the next carry."""
        carry, mean, log_std, _ = self.forward(state_or_params, obs, carry, done)
        u = mean if deterministic else sample_batch(jax.random.split(key, mean.shape[0]), mean, log_std)[0]
        return self.to_box(u), carry


def make_policy(config: PPOConfig, env: Any = None, env_params: Any = None) -> Policy:
    """The policy of ``config`` on ``env`` (default: the Lorenz env with default params)."""
    if env is None:
        from jaxsimrl.envs.lorenz import Lorenz  # the default env only: acting itself needs no env

        env = Lorenz()
    return Policy(config, env, env_params)
