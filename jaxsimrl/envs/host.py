"""HostVecEnv: a batch of host envs (e.g. OpenFOAM cases on a process pool) as a trainer VecEnv.

The batch lives in this Python process and is driven from inside the jitted rollout through
``jax.experimental.io_callback``: **one** ordered callback per env step carrying the whole (N, action)
batch, with fixed-shape, fixed-dtype results; nothing is vmapped and no ``lax.cond`` surrounds it (JAX
refuses to vmap an ordered callback and would serialise an unordered one env by env). The host batch
fans the actions out to its workers and auto-resets finished envs itself (gymnasium's SAME_STEP
mode: ``infos["final_obs"]`` holds the pre-reset observation), so infos and episode records stay on
the host: every ended episode is kept as ``(env_id, final_info)`` until the driver takes them, as data,
after the jitted call (:meth:`HostVecEnv.take_episodes`); ``on_episode(env_id, final_info)``, if given,
is also told of each as it ends (a live progress bar). A done env without a ``final_info``
(a host batch's non-transition after a failed auto-reset) ended no episode.

The callback never raises: solver faults are already outcomes of the batch (an ended episode with a
cause). Anything else that goes wrong on the host (a bug, a broken pool) is caught and kept in
:attr:`HostVecEnv.error`; the callback then returns zeros for the rest of the jitted call without
touching the batch, and the driver raises it as one line once the call has returned
(:meth:`HostVecEnv.raise_if_failed`), before anything of that call is saved. The callback calls no JAX
(a callback that dispatches JAX work can deadlock the CPU client).

The batch is a :class:`jaxsimrl.envs.protocol.HostBatch`: an application's batch of solver cases on a pool
(the OpenFOAM application's BatchedFoamEnv is one).
"""

from __future__ import annotations

import traceback
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import io_callback

from jaxsimrl.envs.protocol import BoxSpec, HostBatch
from jaxsimrl.envs.vec import VecStep

EpisodeHook = Callable[[int, dict[str, Any]], None]


class HostEnvError(RuntimeError):
    """The host side of the env batch failed (not a solver fault: those end episodes)."""


def env_info(infos: dict[str, Any], i: int) -> dict[str, Any]:
    """Env ``i``'s entries of gymnasium-batched infos (nested dicts are batched key by key)."""
    return {key: env_info(value, i) if isinstance(value, dict) else value[i]
            for key, value in infos.items() if not key.startswith("_")}


def _ended_episodes(infos: dict[str, Any], done: np.ndarray) -> np.ndarray:
    """The done envs that ended an episode: those with a final info. A done env without one (a
    non-transition after a failed auto-reset) ended none. Batches without gymnasium's masks ("_final_obs",
    "_final_info"): every done env."""
    if "_final_obs" not in infos:
        return done
    return done & np.asarray(infos.get("_final_info", False), bool)


def _float32_box(spec: Any) -> BoxSpec:
    """The host batch's box (numpy, any dtype) as float32 JAX arrays."""
    return BoxSpec(jnp.asarray(spec.low, jnp.float32), jnp.asarray(spec.high, jnp.float32), tuple(spec.shape))


def seed_of(keys: np.ndarray) -> int:
    """One host seed from a batch of raw PRNG keys (deterministic, any key width)."""
    words = np.asarray(keys).astype(np.uint64).ravel().tolist()
    return int(np.random.SeedSequence(words).generate_state(1)[0])


class HostVecEnv:
    """A host env batch behind one io_callback per step (see the module docstring). The trainer runs it
    on a mesh of one device: sharded envs would make one callback per device, each with part of a batch
    that the host can only step whole."""

    single_device = True

    def __init__(self, batch: HostBatch, on_episode: EpisodeHook | None = None) -> None:
        self.batch = batch
        self.num_envs = int(batch.num_envs)
        self.obs_dim = int(np.prod(batch.observation_spec.shape))
        self.on_episode = on_episode
        self.error: str | None = None
        self._ended: list[tuple[int, dict[str, Any]]] = []  # since the last take_episodes()

    # ---- VecEnv ----------------------------------------------------------------------------------
    def action_space(self) -> BoxSpec:
        return _float32_box(self.batch.action_spec)

    def observation_space(self) -> BoxSpec:
        return _float32_box(self.batch.observation_spec)

    def sample_observations(self, key: jax.Array, count: int) -> None:
        """None: every sample would cost a case build; the normaliser starts empty."""
        return None

    def reset(self, keys: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Reset every env of the batch, seeded from ``keys``; the state is the per-env episode count."""
        shapes = (self._obs_shape(), jax.ShapeDtypeStruct((self.num_envs,), jnp.int32))
        return io_callback(self._host_reset, shapes, keys, ordered=True)

    def step(self, keys: jax.Array, state: jax.Array, actions: jax.Array) -> VecStep:
        """Step the whole batch in one host call (``keys`` are unused: the host batch seeds itself)."""
        n = self.num_envs
        shapes = VecStep(self._obs_shape(), self._obs_shape(), jax.ShapeDtypeStruct((n,), jnp.float32),
                         jax.ShapeDtypeStruct((n,), jnp.bool_), jax.ShapeDtypeStruct((n,), jnp.bool_),
                         jax.ShapeDtypeStruct((n,), jnp.int32), jax.ShapeDtypeStruct((n,), jnp.bool_))
        return io_callback(self._host_step, shapes, state, actions, ordered=True)

    # ---- driver side -----------------------------------------------------------------------------
    def take_episodes(self) -> list[tuple[int, dict[str, Any]]]:
        """The episodes ended since the last call, in order, as ``(env_id, final_info)``; the driver
        takes them after each jitted call (those of a failed call too: it decides to drop them)."""
        ended, self._ended = self._ended, []
        return ended

    def raise_if_failed(self) -> None:
        """After a jitted call: raise the host failure it hit, if any (one line)."""
        if self.error is not None:
            raise HostEnvError(f"the host env batch failed: {self.error}")

    # ---- host callbacks (numpy in, numpy out; never raise) ---------------------------------------
    def _obs_shape(self) -> jax.ShapeDtypeStruct:
        return jax.ShapeDtypeStruct((self.num_envs, self.obs_dim), jnp.float32)

    def _host_reset(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        obs, state = np.zeros((self.num_envs, self.obs_dim), np.float32), np.zeros(self.num_envs, np.int32)
        if self.error is None:
            try:
                obs, state = self._reset(seed_of(keys))
            except Exception as err:  # noqa: BLE001 - reported by raise_if_failed, after the call
                self._fail(err)
        return obs, state

    def _reset(self, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """(first observations, state: the per-env episode counts, zeros)."""
        return self._obs(self.batch.reset(seed=seed)[0]), np.zeros(self.num_envs, np.int32)

    def _host_step(self, state: np.ndarray, actions: np.ndarray) -> VecStep:
        n = self.num_envs
        if self.error is None:
            try:
                return self._step(np.asarray(state), np.asarray(actions, np.float64))
            except Exception as err:  # noqa: BLE001
                self._fail(err)
        zeros = np.zeros((n, self.obs_dim), np.float32)
        return VecStep(zeros, zeros, np.zeros(n, np.float32), np.zeros(n, bool), np.zeros(n, bool),
                       np.asarray(state, np.int32), np.zeros(n, bool))

    def _step(self, episodes: np.ndarray, actions: np.ndarray) -> VecStep:
        obs, reward, terminated, truncated, infos = self.batch.step(actions)
        step = self._results(np.arange(self.num_envs), obs, reward, terminated, truncated, infos)
        return step._replace(state=(episodes + step.ended).astype(np.int32))

    def _results(self, env_ids: np.ndarray, obs: Any, reward: Any, terminated: Any, truncated: Any,
                 infos: dict[str, Any]) -> VecStep:
        """A batch's step results as a VecStep (state None); row ``r`` is env ``env_ids[r]``, whose ended
        episode (``ended[r]``) is kept (and told to ``on_episode``)."""
        obs = self._obs(obs)
        done = np.asarray(terminated, bool) | np.asarray(truncated, bool)
        ended = _ended_episodes(infos, done)
        final_obs = obs.copy()
        for i in np.flatnonzero(done):
            final_obs[i] = np.asarray(infos["final_obs"][i], np.float32)
        for i in np.flatnonzero(ended):
            self._ended.append((int(env_ids[i]), env_info(infos["final_info"], int(i))))
            if self.on_episode is not None:
                self.on_episode(*self._ended[-1])
        return VecStep(obs, final_obs, np.asarray(reward, np.float32), np.asarray(terminated, bool),
                       np.asarray(truncated, bool), None, ended)

    def _obs(self, obs: Any) -> np.ndarray:
        obs = np.asarray(obs, np.float32)
        if obs.shape != (self.num_envs, self.obs_dim):
            raise ValueError(f"the host batch returned observations of shape {obs.shape}, expected "
                             f"{(self.num_envs, self.obs_dim)}")
        return obs

    def _fail(self, err: Exception) -> None:
        where = traceback.extract_tb(err.__traceback__)[-1:]
        place = f" ({where[0].filename}:{where[0].lineno})" if where else ""
        self.error = f"{type(err).__name__}: {err}{place}".replace("\n", " ")
