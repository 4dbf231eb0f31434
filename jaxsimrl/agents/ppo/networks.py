"""The paper's actor-critic in flax.linen: a shared torso, separate actor and critic heads.

torso:  obs -> Dense(64) -> tanh -> Dense(64) -> tanh -> LSTM(256)      (network="lstm")
        obs -> Dense(64) -> tanh -> Dense(64) -> tanh                   (network="mlp")
heads:  actor mean = Dense(action_dim) (small init), state-independent log-std parameter;
        critic value = Dense(1).

Every call works on a time-major sequence: ``obs`` (T, B, obs_dim) and ``starts`` (T, B), where
``starts[t]`` is True when ``obs[t]`` is the first observation of an episode; the recurrent carry is
reset to zeros before such a step, inside the scan. The rollout calls it with T = 1, training with
T = seq_len and the carry stored at the start of each chunk. The MLP network keeps a (B, 1) dummy
carry so both networks share one interface (and RunnerState has the same structure).
"""

from __future__ import annotations

from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np

from jaxsimrl.agents.ppo.config import PPOConfig

Carry = tuple[jax.Array, jax.Array]
_ACTIVATIONS = {"tanh": nn.tanh, "relu": nn.relu}


class ResetLSTM(nn.Module):
    """An LSTM scanned over time whose carry is zeroed where ``starts`` is True."""

    size: int

    @nn.compact
    def __call__(self, carry: Carry, inputs: tuple[jax.Array, jax.Array]) -> tuple[Carry, jax.Array]:
        scan = nn.scan(_ResetCell, variable_broadcast="params", split_rngs={"params": False},
                       in_axes=0, out_axes=0)
        return scan(self.size)(carry, inputs)


class _ResetCell(nn.Module):
    size: int

    @nn.compact
    def __call__(self, carry: Carry, inputs: tuple[jax.Array, jax.Array]) -> tuple[Carry, jax.Array]:
        x, start = inputs
        carry, y = nn.OptimizedLSTMCell(self.size)(reset_carry(carry, start), x)
        return carry, y


class ActorCritic(nn.Module):
    """Gaussian actor (pre-squash mean and log-std) and value critic on a shared torso."""

    action_dim: int
    hidden_sizes: Sequence[int] = (64, 64)
    lstm_size: int = 256
    recurrent: bool = True
    activation: str = "tanh"
    init_log_std: float = -0.5
    init_mean: tuple[float, ...] | None = None  # the mean head's initial bias (pre-squash), zeros if None

    @nn.compact
    def __call__(self, carry: Carry, obs: jax.Array, starts: jax.Array
                 ) -> tuple[Carry, jax.Array, jax.Array, jax.Array]:
        """obs (T, B, obs_dim), starts (T, B) -> (carry, mean (T, B, A), log_std (A,), value (T, B))."""
        act = _ACTIVATIONS[self.activation]
        x = obs
        for size in self.hidden_sizes:
            x = act(nn.Dense(size, kernel_init=nn.initializers.orthogonal(np.sqrt(2)))(x))
        if self.recurrent:
            carry, x = ResetLSTM(self.lstm_size)(carry, (x, starts))
        bias = (nn.initializers.zeros if self.init_mean is None
                else nn.initializers.constant(np.asarray(self.init_mean, np.float32)))
        mean = nn.Dense(self.action_dim, kernel_init=nn.initializers.orthogonal(0.01), bias_init=bias)(x)
        log_std = self.param("log_std", nn.initializers.constant(self.init_log_std), (self.action_dim,))
        value = nn.Dense(1, kernel_init=nn.initializers.orthogonal(1.0),
                         bias_init=nn.initializers.zeros)(x)[..., 0]
        return carry, mean, log_std, value


def make_network(config: PPOConfig, action_dim: int, init_mean: Sequence[float] | None = None
                 ) -> ActorCritic:
    """The actor-critic described by ``config`` (``init_mean``: the mean head's initial bias)."""
    return ActorCritic(action_dim=action_dim, hidden_sizes=tuple(config.hidden_sizes),
                       lstm_size=config.lstm_size, recurrent=config.network == "lstm",
                       activation=config.activation, init_log_std=config.init_log_std,
                       init_mean=None if init_mean is None else tuple(float(m) for m in init_mean))


def initial_carry(config: PPOConfig, batch_size: int) -> Carry:
    """Zero recurrent state for ``batch_size`` envs ((B, 1) dummies for the MLP network)."""
    size = config.lstm_size if config.network == "lstm" else 1
    zeros = jnp.zeros((batch_size, size), jnp.float32)
    return zeros, zeros


def reset_carry(carry: Carry, done: jax.Array) -> Carry:
    """Zero the carry of the envs where ``done`` (B,) is True."""
    keep = (~done)[:, None].astype(carry[0].dtype)
    return carry[0] * keep, carry[1] * keep
