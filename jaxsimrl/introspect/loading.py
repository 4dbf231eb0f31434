"""``load_policy(run_dir)``: a trained policy from a run directory, ready to act in a plain Python session.

The env is rebuilt from the run's config.json (:mod:`jaxsimrl.introspect.envs`), the network from its
PPO config, and only the two parts of the checkpoint that acting needs (network parameters and
observation statistics) are read, as saved, onto one device. A run written by an older version
therefore loads as long as those two still fit the network its config describes; otherwise the error
is one line saying what does not fit.

Every method takes one observation (obs_dim,) or a batch (B, obs_dim) and answers in kind. ``state``
is the recurrent carry returned by the previous call; ``None`` starts an episode. Observations are the
env's raw ones (normalisation is applied inside, as in training), actions are in the env's units and
values in its reward units.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxsimrl.agents.ppo import distribution
from jaxsimrl.agents.ppo.acting import forward, sample_batch
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.networks import Carry, make_network
from jaxsimrl.agents.ppo.normalizer import NormalizerState
from jaxsimrl.agents.ppo.policy import Policy, PolicyParams
from jaxsimrl.introspect.envs import EnvSpec, env_spec, names_for
from jaxsimrl.introspect.squashed import ActionDistribution

Obs = Any  # array-like (obs_dim,) or (B, obs_dim)


class LoadedPolicy:
    """A trained PPO policy with its env; build it with :func:`load_policy` or :meth:`from_params`."""

    def __init__(self, config: PPOConfig, spec: EnvSpec, params: PolicyParams, update: int = 0,
                 env_steps: int = 0, record: dict[str, Any] | None = None, run_dir: Path | None = None,
                 seed: int = 0, checkpoint: int | None = None, agent: int | None = None) -> None:
        self.config = config
        self.env, self.env_params = spec.env, spec.params
        self.policy = Policy(config, spec.env, spec.params)  # the network and action box it trained with
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
        self._rollout = spec.rollout
        self._key = jax.random.PRNGKey(seed)  # the stream stochastic calls draw from when given no key
        self._rollout_cache: dict[tuple[int, int, bool], Any] = {}  # (steps, episodes, deterministic) -> jit

    @classmethod
    def from_params(cls, config: PPOConfig, state_or_params: Any, env: Any = None, env_params: Any = None,
                    **kwargs: Any) -> LoadedPolicy:
        """A policy from a trainer's RunnerState (or PolicyParams) in memory, e.g. straight after
        ``make_train(...).train(key)``; ``env`` defaults to the Lorenz env."""
        from jaxsimrl.introspect.envs import lorenz_spec

        spec = lorenz_spec({}) if env is None else EnvSpec(env, env.default_params(), None, None)
        if env_params is not None:
            spec = EnvSpec(spec.env, env_params, spec.obs_names, spec.action_names)
        params = PolicyParams(state_or_params.params, state_or_params.normalizer)
        return cls(config, spec, params, **kwargs)

    def __repr__(self) -> str:
        where = f" from {self.run_dir}" if self.run_dir else ""
        where += f", agent {self.agent}" if self.agent is not None else ""
        return (f"LoadedPolicy({self.record.get('env', 'env')}, network={self.config.network}, update "
                f"{self.update}, {self.env_steps:,} env steps{where})")

    # ---- acting ------------------------------------------------------------------------------------
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
        return self._answer(self.to_box(u), single), \
            self._carry_out(carry, single)

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
        _, mean, _, _ = forward(self.policy.network.apply, self.config, self.params.params,
                                self.params.normalizer, batched, obs[None], jnp.reshape(start, (1,)))
        return self.to_box(mean[0])

    def to_box(self, u: jax.Array) -> jax.Array:
        """The action in the env's box for pre-squash ``u``, mapped as the policy trained with it."""
        return distribution.to_box(u, self.action_low, self.action_high, self.config.action_margin)

    def rollout(self, env_params: Any = None, steps: int | None = None, episodes: int = 1, seed: int = 0,
                deterministic: bool = True, **options: Any) -> dict[str, np.ndarray]:
        """Run ``episodes`` episodes for ``steps`` steps (default: a whole episode) in the run's env.

        A pure-JAX env (Lorenz): one jitted scan, see :func:`jaxsimrl.introspect.trajectory.rollout` for
        the record's keys. A train-foam run: real simpleFoam episodes, ``episodes`` per inlet velocity of
        ``velocities=`` on ``pool=`` workers, see :func:`jaxsimrl.introspect.foam_rollout.foam_rollout`.
        """
        if self._rollout is None:
            from jaxsimrl.introspect.trajectory import rollout

            if options:
                raise ValueError(f"rollout: unknown option(s) {', '.join(sorted(options))} for this env "
                                 "(velocities= and pool= are for train-foam runs)")
            return rollout(self, env_params, steps, episodes, seed, deterministic)
        return self._rollout(self, env_params, steps, episodes, seed, deterministic, **options)

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
    """``forward`` compiled once per (config, shapes), shared by every LoadedPolicy of that config."""
    return forward(make_network(config, action_dim).apply, config, params, normalizer, carry, obs, starts)


def load_policy(run_dir: str | Path, checkpoint: int | None = None, seed: int = 0,
                agent: int | None = None) -> LoadedPolicy:
    """The policy of ``run_dir``'s last checkpoint (or checkpoint ``checkpoint``, numbered by updates
    done); of a ``--seeds`` run (a batch of agents), that of agent ``agent`` (0-based, required there; see
    :func:`load_agents` for all). Any problem with the run is a one-line ValueError."""
    return _restore(run_dir, checkpoint).agent_policy(agent, seed)


def load_agents(run_dir: str | Path, checkpoint: int | None = None, seed: int = 0) -> list[LoadedPolicy]:
    """Every agent's policy of a run, read from one checkpoint restore: one for a one-agent run, one per
    seed of a ``--seeds`` run (in agent order)."""
    saved = _restore(run_dir, checkpoint)
    seeds = saved.record.get("seeds")
    agents = [None] if seeds is None else range(len(seeds))
    return [saved.agent_policy(agent, seed) for agent in agents]


class _Saved(NamedTuple):
    """A run's config and one checkpoint as saved (a batch run's leaves have a leading agent axis)."""

    run: Any  # RunDir
    record: dict[str, Any]
    config: PPOConfig
    spec: EnvSpec
    tree: Any
    meta: dict[str, Any]
    step: int

    def agent_policy(self, agent: int | None, seed: int) -> LoadedPolicy:
        """The LoadedPolicy of agent ``agent`` of a batch run, or of the one agent (``agent=None``)."""
        self._check_agent(agent)
        tree = self.tree if agent is None else jax.tree.map(lambda leaf: leaf[agent], self.tree)
        where = f"checkpoint {self.step} in {self.run.checkpoints}"
        params = _policy_params(tree, self.config, self.spec, where)
        update = int(np.asarray(tree.get("update_step", self.meta.get("update", self.step))))
        env_steps = int(self.meta.get("env_steps", update * self.config.steps_per_update))
        # an agent of a --sweep trained with its own values of the swept fields
        swept = {name: values[agent] for name, values in self.record.get("sweep", {}).items()}
        config = dataclasses.replace(self.config, **swept) if swept else self.config
        return LoadedPolicy(config, self.spec, params, update, env_steps, self.record, self.run.path,
                            seed, checkpoint=self.step, agent=agent)

    def _check_agent(self, agent: int | None) -> None:
        seeds = self.record.get("seeds")
        if seeds is None and agent is not None:
            raise ValueError(f"{self.run.path} holds one agent (a --seed run): give no agent")
        if seeds is not None and (agent is None or not 0 <= agent < len(seeds)):
            shown = ", ".join(map(str, seeds[:4])) + (", ..." if len(seeds) > 4 else "")
            got = "" if agent is None else f" (got {agent})"
            raise ValueError(f"{self.run.path} holds {len(seeds)} agents (seeds {shown}): pick one with "
                             f"agent K in 0..{len(seeds) - 1}{got}")


def _restore(run_dir: str | Path, checkpoint: int | None) -> _Saved:
    from jaxsimrl.runs.checkpoint import Checkpoints
    from jaxsimrl.runs.run_dir import RunDir

    run = RunDir.existing(run_dir)
    record = run.read_config()
    config = _config_of(run.config, record)
    spec = env_spec(record)
    with Checkpoints(run.checkpoints, writable=False) as checkpoints:
        step = _pick_checkpoint(checkpoints, checkpoint)
        tree, meta = checkpoints.restore_as_saved(step)
    return _Saved(run, record, config, spec, tree, meta, step)


def _config_of(path: Path, record: dict[str, Any]) -> PPOConfig:
    try:
        return PPOConfig.from_dict(record["ppo"])
    except (TypeError, ValueError) as err:  # e.g. a key a newer or older version wrote
        raise ValueError(f"{path}: cannot rebuild the PPO config: {err}") from None


def _pick_checkpoint(checkpoints: Any, wanted: int | None) -> int:
    steps = checkpoints.steps()
    if wanted is None:
        return checkpoints.latest_step()
    if wanted not in steps:
        have = ", ".join(map(str, steps)) or "none"
        raise ValueError(f"no checkpoint {wanted} in {checkpoints.directory} (there are: {have})")
    return wanted


def _policy_params(tree: Any, config: PPOConfig, spec: EnvSpec, where: str) -> PolicyParams:
    """The parameters and normaliser of a restored state, checked against the network of ``config``."""
    if not isinstance(tree, dict) or not {"params", "normalizer"} <= set(tree):
        raise ValueError(f"{where} holds no network parameters and observation statistics "
                         f"(written by an incompatible version)")
    stats = tree["normalizer"]
    normalizer = NormalizerState(count=stats["count"], mean=stats["mean"], m2=stats["m2"])
    obs_dim = int(normalizer.mean.shape[0])
    if spec.obs_dim is not None and obs_dim != spec.obs_dim:
        raise ValueError(f"{where} holds observations of size {obs_dim}, but its config.json's env gives "
                         f"{spec.obs_dim}")
    policy = Policy(config, spec.env, spec.params)
    carry = policy.initial_carry(1)
    expected = jax.eval_shape(policy.network.init, jax.random.PRNGKey(0), carry, jnp.zeros((1, 1, obs_dim)),
                              jnp.ones((1, 1), bool))
    _check_shapes(tree["params"], expected, where)
    return PolicyParams(params=tree["params"], normalizer=normalizer)


def _check_shapes(stored: Any, expected: Any, where: str) -> None:
    flat_stored, flat_expected = _shapes(stored), _shapes(expected)
    if set(flat_stored) != set(flat_expected):
        odd = sorted(set(flat_stored) ^ set(flat_expected))[:2]
        raise ValueError(f"{where} does not fit the network its config.json describes (parameters "
                         f"{', '.join(odd)} differ)")
    for name, shape in flat_expected.items():
        if tuple(flat_stored[name]) != tuple(shape):
            raise ValueError(f"{where} does not fit the network its config.json describes ({name} has shape "
                             f"{tuple(flat_stored[name])}, the config gives {tuple(shape)})")


def _shapes(tree: Any) -> dict[str, tuple[int, ...]]:
    return {jax.tree_util.keystr(path): tuple(leaf.shape)
            for path, leaf in jax.tree_util.tree_flatten_with_path(tree)[0]}
