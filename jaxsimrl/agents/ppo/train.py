"""The PPO train loop: a pure function of a key, jitted whole, sharded over devices.

PureJaxRL-style: ``train(key)`` is one ``jit`` (init, then ``lax.scan`` over all updates); for
progress reports and checkpoints, ``run_chunk(state)`` runs ``updates_per_chunk`` updates per jitted
call on an explicit :class:`RunnerState`. Both run the same update under ``jax.shard_map`` over a 1-D
mesh of devices (axis "envs"): envs (and their rollouts) are split over devices, gradients are
``pmean``-ed and normaliser statistics merged with ``psum``, so the learning does not depend on the
device count. One update = rollout (rollout.py) -> GAE + SGD (learner.py) -> normaliser update.

Every env sits behind a :class:`jaxsimrl.envs.vec.VecEnv`: a pure-JAX env is wrapped in a
:class:`~jaxsimrl.envs.vec.JaxVecEnv` (vmapped, auto-reset with ``where``), a host env batch
(OpenFOAM) is a :class:`~jaxsimrl.envs.host.HostVecEnv` stepped through one ``io_callback`` per step.
Host envs run on a mesh of one device (their batch cannot be split between device shards).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from jaxsimrl.agents.ppo import normalizer as norm
from jaxsimrl.agents.ppo.config import PPOConfig
from jaxsimrl.agents.ppo.learner import gae, learn, make_optimizer
from jaxsimrl.agents.ppo.networks import initial_carry
from jaxsimrl.agents.ppo.policy import Policy
from jaxsimrl.agents.ppo.rollout import RolloutContext, RunnerState, collect, critic_value
from jaxsimrl.agents.ppo.rollout_async import async_advantages, async_env_step, initial_env_state
from jaxsimrl.envs.vec import JaxVecEnv

AXIS = "envs"
_NORMALIZER_SEED_SAMPLES = 1024  # reset observations that seed the normaliser before the first update
_SHARDED_FIELDS = ("env_state", "obs", "starts", "carry", "episode_return")


def _state_specs() -> RunnerState:
    """PartitionSpec prefix tree of RunnerState: env-axis fields sharded, the rest replicated."""
    names = RunnerState.__dataclass_fields__
    fields = {name: (P(AXIS) if name in _SHARDED_FIELDS else P()) for name in names}
    return RunnerState(**fields)


class PPOTrainer:
    """PPO on a batch of envs; build it with :func:`make_train`. ``policy`` acts with its states."""

    def __init__(self, config: PPOConfig, vec: Any, devices: Sequence[jax.Device] | None = None) -> None:
        self.config = config.validate()
        self.vec = vec
        if vec.num_envs != config.num_envs:
            raise ValueError(f"the env batch has {vec.num_envs} envs but num_envs is {config.num_envs}")
        vec_async = getattr(vec, "async_envs", None)
        if vec_async != config.async_envs:
            raise ValueError(f"the env batch has async_envs {vec_async} but the config {config.async_envs}")
        self.devices = list(jax.devices() if devices is None else devices)
        if getattr(vec, "single_device", False) and len(self.devices) > 1:
            raise ValueError(f"a host env batch is stepped whole, from one device; got {len(self.devices)} "
                             f"devices (pass devices=jax.devices()[:1])")
        if config.num_envs % len(self.devices):
            raise ValueError(f"num_envs ({config.num_envs}) must be divisible by the number of devices "
                             f"({len(self.devices)})")
        self.mesh = Mesh(np.array(self.devices), (AXIS,))
        self.num_updates = config.num_updates
        self.num_chunks = math.ceil(self.num_updates / config.updates_per_chunk)
        # acts with the network and action box trained here
        self.policy = Policy(config, _BoxOnly(vec.action_space()))
        self.network = self.policy.network
        self.tx, self.schedule = make_optimizer(config, self.num_updates)
        self.ctx = RolloutContext(self.network.apply, vec, config, self.policy.low, self.policy.high,
                                  config.num_envs // len(self.devices), AXIS)
        self._specs = _state_specs()
        shardings = jax.tree.map(lambda spec: NamedSharding(self.mesh, spec), self._specs,
                                 is_leaf=lambda x: isinstance(x, P))
        self._init_jit = jax.jit(self._init, out_shardings=shardings)  # built in place on the mesh
        self._restart_jit = jax.jit(self._restart, out_shardings=shardings)
        self._chunk = jax.jit(self._sharded(self._run_updates, config.updates_per_chunk))
        self.train = jax.jit(self._train)

    @property
    def env(self) -> Any:
        """The pure-JAX env behind the batch (JaxVecEnv only)."""
        return self.vec.env

    @property
    def env_params(self) -> Any:
        return self.vec.env_params

    # ---- public API ------------------------------------------------------------------------------
    def init(self, key: jax.Array) -> RunnerState:
        """A fresh RunnerState, placed on the mesh (env fields sharded, the rest replicated)."""
        return self._init_jit(key)

    def restart_episodes(self, state: RunnerState, key: jax.Array) -> RunnerState:
        """``state`` with a new episode started in every env (learner fields untouched): a host env
        resumed from a checkpoint, whose solvers did not survive the process, starts here."""
        return self._restart_jit(state, key)

    def run_chunk(self, state: RunnerState) -> tuple[RunnerState, dict[str, jax.Array]]:
        """Run up to ``updates_per_chunk`` updates, never past ``num_updates``.

        The metrics have one row per update actually run (fewer in the last chunk; none when training
        is already complete).
        """
        return run_chunk_with(self._chunk, state, self.config.updates_per_chunk, self.num_updates)

    # ---- pure functions --------------------------------------------------------------------------
    def _init(self, key: jax.Array) -> RunnerState:
        cfg = self.config
        if jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
            key = jax.random.key_data(key)  # keep RunnerState plain uint32 arrays (orbax-saveable)
        net_key, env_key, norm_key, rng = jax.random.split(key, 4)
        obs, env_state = self._reset_envs(env_key)
        carry = initial_carry(cfg, cfg.num_envs)
        starts = jnp.ones(cfg.num_envs, bool)
        params = self.network.init(net_key, initial_carry(cfg, 1), obs[:1][None], starts[:1][None])
        return RunnerState(params=params, opt_state=self.tx.init(params),
                           normalizer=self._seed_normalizer(norm_key), env_state=env_state, obs=obs,
                           starts=starts, carry=carry, episode_return=jnp.zeros(cfg.num_envs, jnp.float32),
                           rng=rng, update_step=jnp.int32(0))

    def _restart(self, state: RunnerState, key: jax.Array) -> RunnerState:
        if jnp.issubdtype(key.dtype, jax.dtypes.prng_key):
            key = jax.random.key_data(key)
        n = self.config.num_envs
        obs, env_state = self._reset_envs(key)
        return state.replace(env_state=env_state, obs=obs, starts=jnp.ones(n, bool),
                             carry=initial_carry(self.config, n), episode_return=jnp.zeros(n, jnp.float32))

    def _reset_envs(self, key: jax.Array) -> tuple[jax.Array, Any]:
        """A new episode in every env: (first observations, env_state); an asynchronous batch's state
        also holds a pending transition per env (none yet)."""
        cfg = self.config
        obs, env_state = self.vec.reset(jax.random.split(key, cfg.num_envs))
        if cfg.async_envs is None:
            return obs, env_state
        return obs, initial_env_state(env_state, cfg.async_envs, obs.shape[-1], self.policy.low.shape[-1])

    def _seed_normalizer(self, key: jax.Array) -> norm.NormalizerState:
        """Statistics of many reset observations, so the first rollout already sees O(1) inputs; envs
        without cheap samples (host envs) start from empty statistics: their own documented scaling."""
        obs = self.vec.sample_observations(key, _NORMALIZER_SEED_SAMPLES)
        if obs is None:
            return norm.init_normalizer(int(np.prod(self.vec.observation_space().shape)))
        return norm.batch_stats(obs)

    def _update(self, state: RunnerState, hparams: dict[str, jax.Array] | None = None
                ) -> tuple[RunnerState, dict[str, jax.Array]]:
        """One PPO update of this device's share of the envs (runs inside shard_map). ``hparams``
        (traced scalars, e.g. one agent's share of a vmapped sweep) replace those config fields."""
        ctx, cfg, tx, schedule = self._setup(hparams)
        rng, rollout_key, learn_key = jax.random.split(state.rng, 3)
        lr = schedule(state.update_step * cfg.update_epochs * cfg.num_minibatches)
        asynchronous = cfg.async_envs is not None
        state, transitions, carries, episodes = collect(ctx, state, rollout_key,
                                                        async_env_step if asynchronous else None)
        last_value = critic_value(ctx, state.params, state.normalizer, state.carry, state.obs, state.starts)
        advantages, targets = (async_advantages(cfg, transitions, state.env_state, last_value) if asynchronous
                               else gae(ctx, transitions, last_value))
        params, opt_state, metrics = learn(ctx, tx, state.params, state.opt_state, transitions, carries,
                                           advantages, targets, learn_key)
        normalizer = state.normalizer
        if cfg.normalize_obs:
            normalizer = norm.update(normalizer, transitions.raw_obs, AXIS)
        returns, count = jax.lax.psum((episodes.return_sum, episodes.count), AXIS)
        update_step = state.update_step + 1
        metrics.update(
            env_steps=update_step * cfg.steps_per_update,
            mean_episode_return=jnp.where(count > 0, returns / jnp.maximum(count, 1.0), jnp.nan),
            episodes=count.astype(jnp.int32), learning_rate=jnp.asarray(lr, jnp.float32))
        state = state.replace(params=params, opt_state=opt_state, normalizer=normalizer, rng=rng,
                              update_step=update_step)
        return state, metrics

    def _setup(self, hparams: dict[str, jax.Array] | None) -> tuple[RolloutContext, PPOConfig, Any, Any]:
        """(rollout context, config, optimizer, lr schedule): the trainer's own, or with ``hparams`` in
        the config. The optimizer's state does not depend on them, so one opt_state fits both."""
        if not hparams:
            return self.ctx, self.config, self.tx, self.schedule
        config = dataclasses.replace(self.config, **hparams)  # no validation runs: values may be traced
        tx, schedule = make_optimizer(config, self.num_updates)
        return self.ctx._replace(config=config), config, tx, schedule

    def _run_updates(self, state: RunnerState, count: int, update: Any = None
                     ) -> tuple[RunnerState, dict[str, jax.Array]]:
        """``count`` updates in a scan; updates past ``num_updates`` are skipped (state unchanged).
        ``update`` defaults to one agent's :meth:`_update`; a seed batch passes it vmapped over agents."""
        update = self._update if update is None else update
        template = jax.eval_shape(update, state)[1]

        def guarded(state: RunnerState, _: None) -> tuple[RunnerState, dict[str, jax.Array]]:
            skip = lambda s: (s, jax.tree.map(lambda t: jnp.zeros(t.shape, t.dtype), template))  # noqa: E731
            # The agents of a batch all have the same update count: testing the first keeps a real branch
            # (a batched predicate would turn the cond into a select that runs both sides).
            done = jnp.ravel(state.update_step)[0]
            return jax.lax.cond(done < self.num_updates, update, skip, state)

        return jax.lax.scan(guarded, state, None, length=count)

    def _sharded(self, fn: Any, count: int) -> Any:
        return jax.shard_map(lambda state: fn(state, count), mesh=self.mesh, in_specs=(self._specs,),
                             out_specs=(self._specs, P()), check_vma=False)

    def _train(self, key: jax.Array) -> tuple[RunnerState, dict[str, jax.Array]]:
        return self._sharded(self._run_updates, self.num_updates)(self._init(key))


def run_chunk_with(chunk: Any, state: RunnerState, per_chunk: int, num_updates: int
                   ) -> tuple[RunnerState, dict[str, jax.Array]]:
    """Run the jitted ``chunk`` on ``state`` and keep the metrics rows of the updates actually run (the
    first axis); shared by one agent and a batch of agents, whose update counts are all equal."""
    done = int(np.ravel(jax.device_get(state.update_step))[0])
    state, metrics = chunk(state)
    ran = max(0, min(per_chunk, num_updates - done))
    return state, {name: value[:ran] for name, value in metrics.items()}


class _BoxOnly:
    """The one thing Policy asks of an env: its action box."""

    def __init__(self, box: Any) -> None:
        self.box = box

    def default_params(self) -> None:
        return None

    def action_space(self, params: Any = None) -> Any:
        return self.box


def make_train(config: PPOConfig, env: Any = None, env_params: Any = None,
               devices: Sequence[jax.Device] | None = None, vec: Any = None) -> PPOTrainer:
    """Build a trainer on a pure-JAX ``env`` (default: the Lorenz env; ``env_params`` default to
    ``env.default_params()``), or on a ready VecEnv ``vec`` (e.g. a host env batch). ``devices``
    default to all of ``jax.devices()`` (num_envs must be divisible by their number)."""
    if vec is None:
        if env is None:
            from jaxsimrl.envs.lorenz import Lorenz

            env = Lorenz()
        vec = JaxVecEnv(env, env_params, config.num_envs)
    elif env is not None or env_params is not None:
        raise ValueError("give either env (and env_params) or vec, not both")
    return PPOTrainer(config, vec, devices)
