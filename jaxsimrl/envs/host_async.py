"""AsyncHostVecEnv: an asynchronous host env batch (EnvPool-style) as the trainer's VecEnv.

It wraps a batch with EnvPool's asynchronous interface (an application's, e.g. the OpenFOAM one's):
``async_envs`` envs on a worker pool, of which each ``recv`` returns the ``num_envs`` that are ready
first (the learner's batch, B rows), with their env ids. The contract with the jitted rollout is
HostVecEnv's (jaxsimrl.envs.host): **one** ordered io_callback per learner step, fixed shapes, never
raising (errors are kept and raised by ``raise_if_failed`` after the call), ended episodes kept as
``(env_id, final_info)`` for ``take_episodes``. What differs is the state: the ids of the B rows.

    obs, ids = vec.reset(keys)          # async_reset, then the first recv
    out = vec.step(keys, ids, actions)  # send(actions, ids), then recv
    out.state                           # (B,) int32: the env of each row of out.obs / reward / ...

Row ``r`` of a step's results is env ``out.state[r]``; its reward, termination, truncation and
``final_obs`` are those of the step that env took since it was last sent (reward 0 and no end for an env's
first appearance after the reset: it completes no step). Pairing each result with the action that
caused it is the rollout's job (jaxsimrl.agents.ppo.rollout_async).

``busy_s`` sums the worker seconds of the steps returned so far, from each step's ``info["step_s"]``
(the batch times its workers' steps): what a utilisation measurement divides by the pool's time. An
episode's ``wall_time_s - solver_idle_s`` would also count the time its step waits in a worker's queue
behind another env's, which the asynchronous batch has by design.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from jaxsimrl.envs.host import EpisodeHook, HostVecEnv
from jaxsimrl.envs.protocol import AsyncHostBatch
from jaxsimrl.envs.vec import VecStep


class AsyncHostVecEnv(HostVecEnv):
    """An asynchronous host batch behind one io_callback per learner step (see the module docstring).
    ``batch`` is a :class:`jaxsimrl.envs.protocol.AsyncHostBatch` (``num_envs``: all its envs,
    ``batch_size``: the rows of a recv)."""

    def __init__(self, batch: AsyncHostBatch, on_episode: EpisodeHook | None = None) -> None:
        super().__init__(batch, on_episode)
        self.async_envs = int(batch.num_envs)
        self.num_envs = int(batch.batch_size)  # the learner's batch: the rows of every call
        self.busy_s = 0.0

    def _reset(self, seed: int) -> tuple[np.ndarray, np.ndarray]:
        """(the first B ready envs' first observations, their ids)."""
        self.batch.async_reset(seed=seed)
        ids, obs, *_ = self.batch.recv()
        return self._obs(obs), np.asarray(ids, np.int32)

    def _step(self, ids: np.ndarray, actions: np.ndarray) -> VecStep:
        self.batch.send(actions, ids)
        ready, obs, reward, terminated, truncated, infos = self.batch.recv()
        self.busy_s += step_seconds(infos)
        step = self._results(np.asarray(ready), obs, reward, terminated, truncated, infos)
        return step._replace(state=np.asarray(ready, np.int32))


def step_seconds(infos: dict[str, Any]) -> float:
    """The worker seconds of the steps in a batch's infos (``step_s``): a row that ended an episode has
    its step's info in ``final_info`` (its top level is the next episode's reset, or, after a failed
    reset, the same step info again); rows without ``step_s`` (resets, lost workers) count nothing."""
    ended = np.asarray(infos.get("_final_info", False), bool)
    return _masked_sum(infos, ~ended) + _masked_sum(infos.get("final_info", {}), ended)


def _masked_sum(infos: dict[str, Any], rows: np.ndarray) -> float:
    """Sum of ``infos["step_s"]`` over ``rows`` that have it."""
    if "step_s" not in infos:
        return 0.0
    seconds = np.asarray(infos["step_s"], object)
    has = np.asarray(infos.get("_step_s", True), bool) & np.broadcast_to(rows, seconds.shape)
    return float(sum(float(s) for s in seconds[has]))
