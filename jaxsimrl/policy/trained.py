"""A trained PPO policy with the env spec it acts in, ready to act in a plain Python session.

Every method takes one observation (obs_dim,) or a batch (B, obs_dim) and answers in kind. ``state``
is the recurrent carry returned by the previous call; ``None`` starts an episode. Observations are the
env's raw ones (normalisation is applied inside, as in training), actions are in the env's units and
values in its reward units. All of it goes through :class:`jaxsimrl.agents.ppo.policy.Policy`, the
network and action box the run trained with. Rolling the policy out in its env is one layer up
(:class:`jaxsimrl.introspect.LoadedPolicy`, what ``jaxsimrl.load_policy`` returns).
"""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from jaxsimrl.agents.ppo.acting import forward, sample_batch
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.networks import Carry, make_network
from jaxsimrl.agents.ppo.normalizer import NormalizerState
from jaxsimrl.agents.ppo.policy import Policy, PolicyParams
from jaxsimrl.policy.distribution import ActionDistribution
from jaxsimrl.policy.spec import EnvSpec, lorenz_spec, names_for

Obs = Any  # array-like (obs_dim,) or (B, obs_dim)


class TrainedPolicy:
    """A trained PPO policy with its env spec; build it with :func:`jaxsimrl.policy.load_policy` or
    :meth:`from_params`."""

    def __init__(self, config: PPOConfig, spec: EnvSpec, params: PolicyParams, update: int = 0,
                 env_steps: int = 0, record: dict[str, Any] | None = None, run_dir: Path | None = None,
                 seed: int = 0, checkpoint: int | None = None, agent: int | None = None) -> None:
        self.config = config
        self.spec = spec
        self.env, self.env_params = spec.env, spec.params
        self.policy = Policy(config, spec.box)  # the network and action box it trained with
        self.params = params
        self.update, self.env_steps = update, env_steps
        self.record = record or {}
        self.run_dir = run_dir
        self.checkpoint = checkpoint  # the checkpoint step it was read from (None: not from a run)
        self.agent = agent  # its index in a --seeds run's batch of agents (None: a one-agent run)
        self.action_low, self.action_high = self.policy.low, self.policy.high
        self.obs_dim = int(params.normalizer.mean.shape[0])
        self.action_dim = int(self.action_low.shape[0])
        self.obs_names = names_for(spec.obs_names, self.obs_dim, "obs")
        self.action_names = names_for(spec.action_names, self.action_dim, "action")
        self.recurrent = config.network == "lstm"
        self._key = jax.random.PRNGKey(seed)  # the stream stochastic calls draw from when given no key

    @classmethod
    def from_params(cls, config: PPOConfig, state_or_params: Any, env: Any = None, env_params: Any = None,
                    **kwargs: Any) -> TrainedPolicy:
        """A policy from a trainer's RunnerState (or PolicyParams) in memory, e.g. straight after
        ``make_train(...).train(key)``; ``env`` defaults to the Lorenz env."""
        spec = lorenz_spec({}) if env is None else EnvSpec.of_env(env)
        if env_params is not None:
            spec = EnvSpec.of_env(spec.env, env_params, spec.obs_names, spec.action_names)
        params = PolicyParams(state_or_params.params, state_or_params.normalizer)
        return cls(config, spec, params, **kwargs)

    def __repr__(self) -> str:
        where = f" from {self.run_dir}" if self.run_dir else ""
        where += f", agent {self.agent}" if self.agent is not None else ""
        return (f"{type(self).__name__}({self.record.get('env', 'env')}, network={self.config.network}, "
                f"update {self.update}, {self.env_steps:,} env steps{where})")

    def initial_state(self, batch_size: int | None = None) -> Carry:
        """The zero carry of an episode start: (H,) pairs, or (B, H) with ``batch_size``."""
        carry = self.policy.initial_carry(1 if batch_size is None else batch_size)
        return jax.tree.map(lambda leaf: leaf[0], carry) if batch_size is None else carry

    def act(self, obs: Obs, state: Carry | None = None, deterministic: bool = True,
            key: jax.Array | int | None = None) -> tuple[np.ndarray, Carry]:
        """(action, next state), like Stable-Baselines3's ``predict``. Stochastic actions use ``key``
        (a PRNG key or an int seed), else the policy's own stream (seeded by ``load_policy(seed=)``)."""
        batch, single = self._batch(obs)
        carry, mean, log_std, _ = self._step(batch, state, single)
        u = mean if deterministic else sample_batch(jax.random.split(self._next_key(key), len(mean)), mean,
                                                    log_std)[0]
        return self._answer(self.to_box(u), single), self._carry_out(carry, single)

    def distribution(self, obs: Obs, state: Carry | None = None) -> ActionDistribution:
        """The action distribution (env units) for ``obs``: median, samples, log_prob, Monte Carlo moments."""
        batch, single = self._batch(obs)
        _, mean, log_std, _ = self._step(batch, state, single)
        mean = mean[0] if single else mean
        scale = jnp.broadcast_to(jnp.exp(log_std), mean.shape)
        return ActionDistribution(mean, scale, self.action_low, self.action_high, self.config.action_margin)

    def value(self, obs: Obs, state: Carry | None = None) -> np.ndarray:
        """The critic's value of ``obs`` in the env's reward units (the critic learns scaled rewards)."""
        batch, single = self._batch(obs)
        value = self._step(batch, state, single)[3] / self.config.reward_scale
        return self._answer(value, single)

    def mean_action(self, obs: jax.Array, carry: Carry, start: jax.Array) -> jax.Array:
        """Deterministic action (A,) of one observation (obs_dim,) from ``carry`` ((H,) pair); pure and
        differentiable in ``obs`` (the sensitivity helper takes its jacobian)."""
        batched = jax.tree.map(lambda leaf: leaf[None], carry)
        _, mean, _, _ = self.policy.forward(self.params, obs[None], batched, jnp.reshape(start, (1,)))
        return self.to_box(mean[0])

    def to_box(self, u: jax.Array) -> jax.Array:
        """The action in the env's box for pre-squash ``u``, mapped as the policy trained with it."""
        return self.policy.to_box(u)

    # ---- batching ----------------------------------------------------------------------------------
    def _batch(self, obs: Obs) -> tuple[jax.Array, bool]:
        array = jnp.asarray(obs, jnp.float32)
        if array.ndim not in (1, 2) or array.shape[-1] != self.obs_dim:
            raise ValueError(f"obs must have shape ({self.obs_dim},) or (B, {self.obs_dim}), got "
                             f"{tuple(array.shape)}")
        return (array[None], True) if array.ndim == 1 else (array, False)

    def _step(self, batch: jax.Array, state: Carry | None, single: bool) -> tuple[Any, ...]:
        size = batch.shape[0]
        if state is None:
            carry, starts = self.policy.initial_carry(size), jnp.ones(size, bool)
        else:
            carry = jax.tree.map(lambda leaf: jnp.asarray(leaf)[None] if single else jnp.asarray(leaf), state)
            starts = jnp.zeros(size, bool)
        acting = self.params
        return _forward(self.config, self.action_dim, acting.params, acting.normalizer, carry, batch, starts)

    def _next_key(self, key: jax.Array | int | None) -> jax.Array:
        if key is None:
            self._key, key = jax.random.split(self._key)
            return key
        return jax.random.PRNGKey(int(key)) if isinstance(key, int | np.integer) else key

    @staticmethod
    def _answer(values: jax.Array, single: bool) -> np.ndarray:
        values = np.asarray(values)
        return values[0] if single else values

    @staticmethod
    def _carry_out(carry: Carry, single: bool) -> Carry:
        return jax.tree.map(lambda leaf: leaf[0], carry) if single else carry


@functools.partial(jax.jit, static_argnums=(0, 1))
def _forward(config: PPOConfig, action_dim: int, params: Any, normalizer: NormalizerState, carry: Carry,
             obs: jax.Array, starts: jax.Array) -> tuple[Any, ...]:
    """``forward`` compiled once per (config, shapes), shared by every TrainedPolicy of that config."""
    return forward(make_network(config, action_dim).apply, config, params, normalizer, carry, obs, starts)
