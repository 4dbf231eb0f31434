"""BatchedFoamEnv: N simpleFoam cases stepped in parallel on a worker pool, auto-reset on the host.

    env = BatchedFoamEnv(cfg, num_envs=4, pool=2, seed=0)        # backend="ray" for Ray actors
    obs, infos = env.reset()                                      # obs [N, obs_dim] float32
    obs, reward, terminated, truncated, infos = env.step(actions)  # actions [N, 2 or 3]: the factors

Auto-reset follows gymnasium's "same step" mode: when env ``i`` ends an episode, ``obs[i]`` is
already the first observation of its next episode, ``infos["final_obs"][i]`` and
``infos["final_info"]`` (masked by ``infos["_final_info"]``) hold the last observation and info of the
ended one, and ``infos`` itself carries the reset info for ``i``. Infos are batched the gymnasium way:
``infos[key]`` is an array over envs, ``infos["_" + key]`` marks which envs have the key.

Seeding: ``seed`` (int, or one int per env) seeds one random stream per env; every episode, including
auto-resets and the episode after a worker crash, is reset with a seed drawn from its env's stream.
So the same seed and actions give the same episodes on any backend and after worker restarts.
:meth:`BatchedFoamEnv.snapshot` and :meth:`BatchedFoamEnv.replay` carry the running episodes (and the
streams) over to a new batch, e.g. across a training run's resume.

``step()`` never raises for a solver or worker fault (only for bad actions): a solver that crashed,
diverged or hung ends its episode with that outcome; a dead or hung worker ends the episodes of its
envs with outcome "crashed", cause "worker died" (a Ray node that died: "node lost: IP/NODE") and the
config's failure penalty, and is replaced (where there is no room for a replacement, its envs move to
the other workers: ``backend.workers()``, ``backend.lost``; none left: PoolLostError);
an auto-reset that fails (however many workers die, or the case breaks) leaves the env waiting for a
reset, retried before its next step; while that fails, each step of that env is a failed episode of
0 iterations with cause "reset failed: ...". The step whose retry succeeds does not apply the env's
action (it was chosen from the ended episode's last observation, ``obs[i]`` after the failed reset):
it is a non-transition, reward 0, ``truncated`` (the learner bootstraps from ``infos["final_obs"][i]``,
that last observation) with no ``final_info``, and ``obs[i]`` is the new episode's first observation,
so its first action is chosen from it. The other envs go on in every case. (``reset()`` itself
raises when an env cannot start at all: a broken case or setup is the caller's to fix.)
"""

from __future__ import annotations

import os
import shutil
import time
from dataclasses import dataclass, field
from typing import Any, Self

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv

from foam_bridge._backends import (
    BAD_INPUT_ERRORS,
    WORKER_DIED,
    EnvFactory,
    Reply,
    Request,
    make_backend,
    validate_pool,
)
from foam_bridge._config import (  # failure_reward: re-exported
    ACTION_NAMES,
    FoamEnvConfig,
    cost_per_iteration,
    failure_reward,
)
from foam_bridge._env import action_spec, observation_spec
from foam_bridge._records import EpisodeRecord
from foam_bridge._replay import EpisodeReplay
from foam_bridge._work_dirs import work_root

__all__ = ["SEED_BOUND", "BatchedFoamEnv", "FoamBatchCore"]

SEED_BOUND = 2**31 - 1


class _InfoBatcher(VectorEnv):
    """Borrows gymnasium's own info batching (``_add_info``), so the layout is exactly gymnasium's."""

    def __init__(self, num_envs: int) -> None:
        self.num_envs = num_envs

    def add(self, infos: dict[str, Any], info: dict[str, Any], env_id: int) -> dict[str, Any]:
        _widen(infos, info)
        return self._add_info(infos, info, env_id)


def _widen(infos: dict[str, Any], info: dict[str, Any]) -> None:
    """Widen the arrays of ``infos`` that cannot hold ``info``'s value for their key.

    gymnasium types a key's array by the first env that has it: a solver's record (integer counts) and
    a record the host wrote for a lost worker (NaN, None) can end in the same step, in either order.
    """
    for key, value in info.items():
        array = infos.get(key)
        if isinstance(value, dict) and isinstance(array, dict):
            _widen(array, value)
        elif isinstance(array, np.ndarray) and array.ndim == 1 and array.dtype != object:
            if isinstance(value, float | np.floating) and array.dtype.kind in "biu":
                infos[key] = array.astype(np.float64)
            elif not isinstance(value, int | float | bool | np.number):
                infos[key] = array.astype(object)


@dataclass
class _Tally:
    """What the host knows of one env's running episode (enough to record it if its worker dies)."""

    obs: np.ndarray
    seed: int | None = None
    inlet_velocity: float = float("nan")
    step_height: float = float("nan")
    iterations: int = 0
    episode_return: float = 0.0
    residuals: dict[str, float] = field(default_factory=dict)
    actions: list[list[float]] = field(default_factory=list)
    started: float = field(default_factory=time.monotonic)
    #: Why the env has no running episode (its auto-reset failed); "" while it has one.
    reset_failure: str = ""
    #: Where the episode runs (Backend.node_of at its reset): its record's "node".
    node: str = ""


class FoamBatchCore(EpisodeReplay):
    """What a batch of foam envs on a worker pool keeps, whatever order it steps them in: the pool, the
    per-env seed streams and the tallies of the running episodes, from which it writes the record of an
    episode its env could not report, and replays them in another batch (foam_bridge._replay).
    BatchedFoamEnv (lock-step) and foam_bridge._async_batch build on it."""

    def __init__(
        self,
        cfg: FoamEnvConfig,
        num_envs: int,
        backend: str = "local",
        pool: int | None = None,
        ray_address: str | None = None,
        work_dir: str | os.PathLike[str] | None = None,
        seed: int | list[int] | None = None,
        make_env: EnvFactory | None = None,
    ) -> None:
        self.cfg = cfg = cfg.validate().with_absolute_paths()
        pool = validate_pool(num_envs, pool)  # bad sizes fail before anything is created
        self.num_envs = num_envs
        self.observation_spec = observation_spec(cfg)
        self.action_spec = action_spec(cfg)
        self._batcher = _InfoBatcher(num_envs)
        self._streams = self._seed_streams(seed)
        self._tallies = [_Tally(np.zeros(cfg.observation_size, np.float32)) for _ in range(num_envs)]
        self.work_dir, self._temp_dir = work_root(cfg, work_dir)
        try:
            self.backend = make_backend(backend, cfg, num_envs, pool, self.work_dir, ray_address,
                                        make_env)
        except BaseException:
            if self._temp_dir:
                shutil.rmtree(self.work_dir, ignore_errors=True)
            raise
        self._closed = False

    # ----- seeding -----------------------------------------------------------------------------
    def _seed_streams(self, seed: int | list[int] | None) -> list[np.random.Generator]:
        if isinstance(seed, list | tuple):
            if len(seed) != self.num_envs:
                raise ValueError(f"seed: expected one seed per env ({self.num_envs}), got {len(seed)}")
            return [np.random.default_rng(np.random.SeedSequence(int(s))) for s in seed]
        return [np.random.default_rng(child) for child in np.random.SeedSequence(seed).spawn(self.num_envs)]

    def _episode_seed(self, env_id: int) -> int:
        return int(self._streams[env_id].integers(SEED_BOUND))

    def _reset_envs(
        self, env_ids: list[int], options: dict[str, Any] | None = None
    ) -> tuple[dict[int, tuple], dict[int, Reply]]:
        """Reset some envs in parallel, each with the next seed of its stream and ``options``."""
        return self.run_resets({i: self._episode_seed(i) for i in env_ids}, dict.fromkeys(env_ids, options))

    # ----- the one place that drives solvers: every front-end's resets and steps go through here ------
    def _reset_request(self, env_id: int, seed: int, options: dict[str, Any] | None = None) -> Request:
        return Request(env_id, "reset", {"seed": seed, "options": options})

    def _step_request(self, env_id: int, action: np.ndarray) -> Request:
        return Request(env_id, "step", {"action": action})

    def run_resets(
        self, seeds: dict[int, int], options: dict[int, dict[str, Any] | None]
    ) -> tuple[dict[int, tuple], dict[int, Reply]]:
        """Reset the envs of ``seeds`` in parallel, each with its seed and options; a worker that dies
        during a reset gets one more try. Returns (env -> (obs, info) of the reset ones, env -> the failed
        Reply of the others)."""
        results: dict[int, tuple] = {}
        failures: dict[int, Reply] = {}
        pending = list(seeds)
        for attempt in range(2):
            requests = [self._reset_request(i, seeds[i], options.get(i)) for i in pending]
            pending = []
            for reply in self.backend.run(requests):
                if reply.ok:
                    results[reply.env_id] = self._start_tally(reply.env_id, seeds[reply.env_id], *reply.value)
                elif reply.worker_died and attempt == 0:
                    pending.append(reply.env_id)
                else:
                    failures[reply.env_id] = reply
            if not pending:
                break
        return results, failures

    def run_steps(self, actions: dict[int, np.ndarray]) -> tuple[dict[int, tuple], set[int]]:
        """Step the envs of ``actions`` in parallel. Returns (env -> its step result, the envs the
        solver's side could not answer: their result is :meth:`_failed_step`'s, a crashed episode)."""
        lost = {i: reply for i in actions if (reply := self._stranded(i)) is not None}
        replies = self.backend.run([self._step_request(i, a) for i, a in actions.items() if i not in lost])
        replies += lost.values()
        results = {reply.env_id: self._step_result(reply, actions[reply.env_id]) for reply in replies}
        return results, {reply.env_id for reply in replies if not reply.ok}

    def _start_tally(self, env_id: int, seed: int, obs: Any, info: dict[str, Any]) -> tuple[np.ndarray, dict]:
        self.backend.stranded.pop(env_id, None)  # a new episode on the worker it lives on now
        obs = np.asarray(obs, np.float32)
        velocity = float(info.get("inlet_velocity", np.nan))
        height = info.get("step_height")
        self._tallies[env_id] = _Tally(obs, seed=seed, inlet_velocity=velocity,
                                       step_height=float("nan") if height is None else float(height),
                                       residuals=dict(info.get("residuals", {})),
                                       node=self.backend.node_of(env_id))
        return obs, info

    def _stranded(self, env_id: int) -> Reply | None:
        """The reply a step of ``env_id`` gets when its episode died with its worker while the env had
        no request there (Backend.stranded): the worker's own, without sending the step to a fresh worker
        that has no episode to step."""
        cause = self.backend.stranded.pop(env_id, None)
        return None if cause is None else Reply(env_id, False, error=cause, worker_died=True)

    def _step_result(self, reply: Reply, action: np.ndarray) -> tuple:
        tally = self._tallies[reply.env_id]
        if reply.ok:
            tally.actions.append([float(a) for a in action])
            obs, reward, term, trunc, info = reply.value
            tally.obs = np.asarray(obs, np.float32)
            tally.iterations = int(info.get("iterations", tally.iterations))
            tally.residuals = dict(info.get("residuals", tally.residuals))
            tally.episode_return += float(reward)
            return tally.obs, float(reward), bool(term), bool(trunc), info
        cause = ((reply.error or WORKER_DIED) if reply.worker_died
                 else f"worker error: {reply.error} ({reply.where})")
        return self._failed_step(tally, action, cause)

    def _failed_step(self, tally: _Tally, action: np.ndarray, cause: str) -> tuple:
        """The step result of an episode the env itself could not report: crashed, with the penalty."""
        tally.actions.append([float(a) for a in action])
        rate = cost_per_iteration(self.cfg, -tally.episode_return, tally.iterations)
        reward = failure_reward(self.cfg, tally.iterations, rate) * self.cfg.reward_scale
        tally.episode_return += reward
        return tally.obs, reward, True, False, self._failure_info(tally, cause)

    def _failure_info(self, tally: _Tally, cause: str) -> dict[str, Any]:
        """The info (with episode record) of an episode the env itself could not report."""
        record = EpisodeRecord(
            outcome="crashed", cause=cause, iterations=tally.iterations, seed=tally.seed,
            inlet_velocity=tally.inlet_velocity, step_height=tally.step_height, actions=list(tally.actions),
            episode_return=tally.episode_return, wall_time_s=time.monotonic() - tally.started,
            residuals=dict(tally.residuals), node=tally.node,
        ).to_json()
        return {"iterations": tally.iterations, "residuals": dict(tally.residuals), "outcome": "crashed",
                "cause": cause, "inlet_velocity": tally.inlet_velocity, "episode": record}

    def _observations(self) -> np.ndarray:
        return np.stack([tally.obs for tally in self._tallies]).astype(np.float32)

    # ----- misc --------------------------------------------------------------------------------
    def iterations(self) -> np.ndarray:
        """Cumulative SIMPLE iterations of each env's current episode."""
        return np.array([tally.iterations for tally in self._tallies], np.int32)

    def worker_pids(self) -> list[int]:
        """Process id of the worker hosting each env (env i -> entry i)."""
        return [self.backend.worker_pid(i) for i in range(self.num_envs)]

    def close(self) -> None:
        """Close every env (their solvers die), stop the workers, drop a temporary work_dir. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self.backend.close()
        if self._temp_dir and not self.cfg.keep_cases:
            shutil.rmtree(self.work_dir, ignore_errors=True)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        if not getattr(self, "_closed", True):
            self.close()


class BatchedFoamEnv(FoamBatchCore):
    """``num_envs`` FoamCaseEnv cases on a ``pool`` of workers, stepped in lock-step (see the module
    docstring). ``make_env``: what each worker builds in place of a FoamCaseEnv (foam_bridge._standin)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    # ----- reset -------------------------------------------------------------------------------
    def reset(
        self, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """New episode in every env. ``seed`` re-seeds the per-env streams; ``options`` go to every env."""
        if seed is not None:
            self._streams = self._seed_streams(seed)
        infos: dict[str, Any] = {}
        results, failures = self._reset_envs(list(range(self.num_envs)), options)
        if failures:
            raise _reset_error(failures[min(failures)])
        for env_id, (_, info) in results.items():
            infos = self._batcher.add(infos, info, env_id)
        return self._observations(), infos

    def _retry_resets(self) -> tuple[dict[int, tuple], dict[int, str]]:
        """Reset the envs whose auto-reset failed. Returns (env -> (the ended episode's last observation,
        the reset info) for those that have an episode now, env -> cause for those that fail again)."""
        waiting = [i for i, tally in enumerate(self._tallies) if tally.reset_failure]
        if not waiting:
            return {}, {}
        stale = {i: self._tallies[i].obs for i in waiting}
        results, failures = self._reset_envs(waiting)
        return ({i: (stale[i], info) for i, (_, info) in results.items()},
                {i: _reset_cause(reply) for i, reply in failures.items()})

    # ----- step --------------------------------------------------------------------------------
    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with its (alpha_u, alpha_p[, alpha_t]); auto-reset the ones whose episode ended."""
        actions = np.asarray(actions, np.float64)
        size = self.cfg.action_size
        names = ", ".join(ACTION_NAMES[:size])
        if actions.shape != (self.num_envs, size):
            raise ValueError(f"actions: expected shape ({self.num_envs}, {size}), got {actions.shape}")
        if not np.isfinite(actions).all():  # an agent bug, not a solver failure: refuse, as FoamCaseEnv does
            raise ValueError(f"actions: expected finite ({names}), got {actions.tolist()}")
        restarted, unstarted = self._retry_resets()
        runnable = [i for i in range(self.num_envs) if i not in unstarted and i not in restarted]
        results, _ = self.run_steps({i: actions[i] for i in runnable})
        for i, cause in unstarted.items():  # no episode to step: a failed one of 0 iterations
            self._tallies[i] = _Tally(self._tallies[i].obs)
            results[i] = self._failed_step(self._tallies[i], actions[i], cause)
        for i, (stale, info) in restarted.items():  # its action was chosen from ``stale``: not applied
            results[i] = (stale, 0.0, False, True, info)
        rewards = np.array([results[i][1] for i in range(self.num_envs)], np.float64)
        terminated = np.array([results[i][2] for i in range(self.num_envs)], bool)
        truncated = np.array([results[i][3] for i in range(self.num_envs)], bool)
        step_infos = [results[i][4] for i in range(self.num_envs)]
        ended = (terminated | truncated) & ~np.isin(np.arange(self.num_envs), list(restarted))
        infos = self._autoreset(ended, step_infos)  # before reading obs: resets replace them
        for i, (stale, _) in restarted.items():  # no episode ended: a final observation, no final info
            infos = self._batcher.add(infos, {"final_obs": stale}, i)
        return self._observations(), rewards, terminated, truncated, infos

    def _autoreset(self, done: np.ndarray, step_infos: list[dict[str, Any]]) -> dict[str, Any]:
        infos: dict[str, Any] = {}
        finished = [int(i) for i in np.flatnonzero(done)]
        for i in finished:
            if isinstance(step_infos[i].get("episode"), dict):  # the env's own record: say where it ran
                step_infos[i]["episode"].setdefault("node", self._tallies[i].node)
            final = {"final_obs": self._tallies[i].obs, "final_info": step_infos[i]}
            infos = self._batcher.add(infos, final, i)
        results, failures = self._reset_envs(finished) if finished else ({}, {})
        reset_infos = {i: info for i, (_, info) in results.items()}
        for i, reply in failures.items():  # retried before the env's next step; obs stays the final one
            self._tallies[i].reset_failure = _reset_cause(reply)
        for i in range(self.num_envs):
            infos = self._batcher.add(infos, reset_infos.get(i, step_infos[i]), i)
        return infos

    # ----- resuming ----------------------------------------------------------------------------
    def snapshot(self) -> list[dict[str, Any]]:
        """Each env's running episode as JSON-ready data, enough for :meth:`replay` in another batch
        (another process): its reset seed, the actions taken, K, return and last observation, and the
        env's seed stream (the seeds of the episodes to come)."""
        return [self._episode_entry(i) for i in range(self.num_envs)]

    def replay(self, snapshot: list[dict[str, Any]]) -> str:
        """Bring every env to the episode state of ``snapshot``: reset it with the episode's seed and step
        the same actions (the solver is deterministic), check K, the return and the observation, and
        restore the seed streams. Returns "" when every env matches; otherwise why not, and the
        batch must be reset before it is used."""
        if len(snapshot) != self.num_envs or not all(entry.get("running") for entry in snapshot):
            return f"the snapshot does not hold a running episode for each of the {self.num_envs} envs"
        why = self._replay_episodes(dict(enumerate(snapshot)))
        if not why:
            self._restore_streams(snapshot)
        return why


def _reset_cause(reply: Reply) -> str:
    return f"reset failed: {(reply.error or WORKER_DIED) if reply.worker_died else reply.error}"


def _reset_error(reply: Reply) -> Exception:
    """A reset that failed for a reason other than a (first) worker death: bad input or a broken setup."""
    message = f"env {reply.env_id}: reset failed: {reply.error}"
    return ValueError(message) if reply.kind in BAD_INPUT_ERRORS else RuntimeError(message)
