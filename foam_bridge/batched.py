"""BatchedFoamEnv: N simpleFoam cases stepped in parallel on a worker pool, auto-reset on the host.

    env = BatchedFoamEnv(cfg, num_envs=4, pool=2, seed=0)        # backend="ray" for Ray actors
    obs, infos = env.reset()                                      # obs [N, obs_dim] float32
    obs, reward, terminated, truncated, infos = env.step(actions)  # actions [N, 2] = (alpha_u, alpha_p)

Auto-reset follows gymnasium's "same step" mode: when env ``i`` ends an episode, ``obs[i]`` is
already the first observation of its next episode, ``infos["final_obs"][i]`` and
``infos["final_info"]`` (masked by ``infos["_final_info"]``) hold the last observation and info of the
ended one, and ``infos`` itself carries the reset info for ``i``. Infos are batched the gymnasium way:
``infos[key]`` is an array over envs, ``infos["_" + key]`` marks which envs have the key.

Seeding: ``seed`` (int, or one int per env) seeds one random stream per env; every episode, including
auto-resets and the episode after a worker crash, is reset with a seed drawn from its env's stream.
So the same seed and actions give the same episodes on any backend and after worker restarts.

Failures never raise: a dead or hung worker ends that env's episode with outcome "crashed", cause
"worker died" and the config's failure penalty; the worker is replaced and the other envs go on.

``BatchedFoamEnv.protocol()`` gives the same batch in the jaxsimrl protocol form (reset(key, params),
step(key, state, action, params)) with numpy arrays, for a JAX trainer stepping it via io_callback.
"""

from __future__ import annotations

import os
import shutil
import time
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv

from foam_bridge.backends import BAD_INPUT_ERRORS, WORKER_DIED, Reply, Request, make_backend, validate_pool
from foam_bridge.config import FoamEnvConfig, failure_reward, work_root  # failure_reward: re-exported
from foam_bridge.env import action_spec, observation_spec, seed_from_key
from jaxsimrl.envs.protocol import BoxSpec, Step

SEED_BOUND = 2**31 - 1


class _InfoBatcher(VectorEnv):
    """Borrows gymnasium's own info batching (``_add_info``), so the layout is exactly gymnasium's."""

    def __init__(self, num_envs: int) -> None:
        self.num_envs = num_envs

    def add(self, infos: dict[str, Any], info: dict[str, Any], env_id: int) -> dict[str, Any]:
        return self._add_info(infos, info, env_id)


@dataclass
class _Tally:
    """What the host knows of one env's running episode (enough to record it if its worker dies)."""

    obs: np.ndarray
    inlet_velocity: float = float("nan")
    iterations: int = 0
    episode_return: float = 0.0
    residuals: dict[str, float] = field(default_factory=dict)
    actions: list[list[float]] = field(default_factory=list)
    started: float = field(default_factory=time.monotonic)


class BatchedFoamEnv:
    """``num_envs`` FoamCaseEnv cases on a ``pool`` of workers (see the module docstring)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(
        self,
        cfg: FoamEnvConfig,
        num_envs: int,
        backend: str = "local",
        pool: int | None = None,
        ray_address: str | None = None,
        work_dir: str | os.PathLike[str] | None = None,
        seed: int | list[int] | None = None,
    ) -> None:
        self.cfg = cfg.validate()
        pool = validate_pool(num_envs, pool)  # bad sizes fail before anything is created
        self.num_envs = num_envs
        self.observation_spec = observation_spec(cfg)
        self.action_spec = action_spec(cfg)
        self._batcher = _InfoBatcher(num_envs)
        self._streams = self._seed_streams(seed)
        self._tallies = [_Tally(np.zeros(cfg.observation_size, np.float32)) for _ in range(num_envs)]
        self.work_dir, self._temp_dir = work_root(cfg, work_dir)
        try:
            self.backend = make_backend(backend, cfg, num_envs, pool, self.work_dir, ray_address)
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

    # ----- reset -------------------------------------------------------------------------------
    def reset(
        self, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """New episode in every env. ``seed`` re-seeds the per-env streams; ``options`` go to every env."""
        if seed is not None:
            self._streams = self._seed_streams(seed)
        infos: dict[str, Any] = {}
        for env_id, (_, info) in self._reset_envs(list(range(self.num_envs)), options).items():
            infos = self._batcher.add(infos, info, env_id)
        return self._observations(), infos

    def _reset_envs(self, env_ids: list[int], options: dict[str, Any] | None = None) -> dict[int, tuple]:
        """Reset some envs in parallel; a worker that dies during reset gets one more try."""
        seeds = {i: self._episode_seed(i) for i in env_ids}
        results: dict[int, tuple] = {}
        pending = list(env_ids)
        for attempt in range(2):
            requests = [Request(i, "reset", {"seed": seeds[i], "options": options}) for i in pending]
            failed = []
            for reply in self.backend.run(requests):
                if reply.ok:
                    results[reply.env_id] = self._start_tally(reply.env_id, *reply.value)
                elif reply.worker_died and attempt == 0:
                    failed.append(reply.env_id)
                else:
                    raise _reset_error(reply)
            pending = failed
            if not pending:
                break
        return results

    def _start_tally(self, env_id: int, obs: Any, info: dict[str, Any]) -> tuple[np.ndarray, dict[str, Any]]:
        obs = np.asarray(obs, np.float32)
        self._tallies[env_id] = _Tally(obs, inlet_velocity=float(info.get("inlet_velocity", np.nan)),
                                       residuals=dict(info.get("residuals", {})))
        return obs, info

    # ----- step --------------------------------------------------------------------------------
    def step(self, actions: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Step every env with its (alpha_u, alpha_p); auto-reset the ones whose episode ended."""
        actions = np.asarray(actions, np.float64)
        if actions.shape != (self.num_envs, 2):
            raise ValueError(f"actions: expected shape ({self.num_envs}, 2), got {actions.shape}")
        if not np.isfinite(actions).all():  # an agent bug, not a solver failure: refuse, as FoamCaseEnv does
            raise ValueError(f"actions: expected finite (alpha_u, alpha_p), got {actions.tolist()}")
        replies = self.backend.run([Request(i, "step", {"action": actions[i]}) for i in range(self.num_envs)])
        rewards = np.zeros(self.num_envs, np.float64)
        terminated = np.zeros(self.num_envs, bool)
        truncated = np.zeros(self.num_envs, bool)
        step_infos: list[dict[str, Any]] = []
        for reply in replies:
            i = reply.env_id
            obs, reward, term, trunc, info = self._step_result(reply, actions[i])
            rewards[i], terminated[i], truncated[i] = reward, term, trunc
            step_infos.append(info)
        infos = self._autoreset(terminated | truncated, step_infos)  # before reading obs: resets replace them
        return self._observations(), rewards, terminated, truncated, infos

    def _step_result(self, reply: Reply, action: np.ndarray) -> tuple:
        tally = self._tallies[reply.env_id]
        tally.actions.append([float(a) for a in action])
        if reply.ok:
            obs, reward, term, trunc, info = reply.value
            tally.obs = np.asarray(obs, np.float32)
            tally.iterations = int(info.get("iterations", tally.iterations))
            tally.residuals = dict(info.get("residuals", tally.residuals))
            tally.episode_return += float(reward)
            return tally.obs, float(reward), bool(term), bool(trunc), info
        cause = WORKER_DIED if reply.worker_died else f"worker error: {reply.error} ({reply.where})"
        reward = failure_reward(self.cfg, tally.iterations)
        tally.episode_return += reward
        return tally.obs, reward, True, False, self._failure_info(tally, cause)

    def _failure_info(self, tally: _Tally, cause: str) -> dict[str, Any]:
        """The info (with episode record) of an episode the env itself could not report."""
        record = {
            "outcome": "crashed", "cause": cause, "iterations": tally.iterations,
            "return": tally.episode_return, "actions": list(tally.actions),
            "inlet_velocity": tally.inlet_velocity, "wall_time_s": time.monotonic() - tally.started,
        }
        return {"iterations": tally.iterations, "residuals": dict(tally.residuals), "outcome": "crashed",
                "cause": cause, "inlet_velocity": tally.inlet_velocity, "episode": record}

    def _autoreset(self, done: np.ndarray, step_infos: list[dict[str, Any]]) -> dict[str, Any]:
        infos: dict[str, Any] = {}
        finished = [int(i) for i in np.flatnonzero(done)]
        for i in finished:
            final = {"final_obs": self._tallies[i].obs, "final_info": step_infos[i]}
            infos = self._batcher.add(infos, final, i)
        reset_infos = {i: info for i, (_, info) in self._reset_envs(finished).items()} if finished else {}
        for i in range(self.num_envs):
            infos = self._batcher.add(infos, reset_infos.get(i, step_infos[i]), i)
        return infos

    def _observations(self) -> np.ndarray:
        return np.stack([tally.obs for tally in self._tallies]).astype(np.float32)

    # ----- misc --------------------------------------------------------------------------------
    def iterations(self) -> np.ndarray:
        """Cumulative SIMPLE iterations of each env's current episode."""
        return np.array([tally.iterations for tally in self._tallies], np.int32)

    def worker_pids(self) -> list[int]:
        """Process id of the worker hosting each env (env i -> entry i)."""
        return [self.backend.worker_pid(i) for i in range(self.num_envs)]

    def protocol(self) -> BatchedFoamProtocol:
        """This batch in the jaxsimrl protocol form (see BatchedFoamProtocol)."""
        return BatchedFoamProtocol(self)

    def close(self) -> None:
        """Close every env (their solvers die), stop the workers, drop a temporary work_dir. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self.backend.close()
        if self._temp_dir and not self.cfg.keep_cases:
            shutil.rmtree(self.work_dir, ignore_errors=True)

    def __enter__(self) -> BatchedFoamEnv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        if not getattr(self, "_closed", True):
            self.close()


def _reset_error(reply: Reply) -> Exception:
    """A reset that failed for a reason other than a (first) worker death: bad input or a broken setup."""
    message = f"env {reply.env_id}: reset failed: {reply.error}"
    return ValueError(message) if reply.kind in BAD_INPUT_ERRORS else RuntimeError(message)


class BatchedState(NamedTuple):
    """Host-side state handle of the protocol form: episodes ended and iterations, per env (int32 [N])."""

    episode: np.ndarray
    iterations: np.ndarray


class BatchedFoamProtocol:
    """A BatchedFoamEnv in the protocol form: plain numpy in, numpy out (io_callback friendly).

    ``reset(key, params)`` re-seeds every env from ``key`` and resets them all; ``step`` steps all envs
    and auto-resets finished ones (the batch is a host env: its solvers cannot be rewound, so the
    trainer never resets it itself). ``params`` must be None or the batch's own config: a running
    batch cannot change its cases. The returned state is a handle (episode counters, iterations), not
    the solver state; passing an old one does not rewind anything.
    """

    def __init__(self, env: BatchedFoamEnv) -> None:
        self.env = env
        self._episodes = np.zeros(env.num_envs, np.int32)

    def default_params(self) -> FoamEnvConfig:
        return self.env.cfg

    def _check(self, params: Any) -> None:
        if params is not None and params is not self.env.cfg and params != self.env.cfg:
            raise ValueError("params: a BatchedFoamEnv runs with the config it was built with")

    def observation_space(self, params: Any = None) -> BoxSpec:
        return self.env.observation_spec

    def action_space(self, params: Any = None) -> BoxSpec:
        return self.env.action_spec

    def reset(self, key: Any, params: Any = None) -> tuple[np.ndarray, BatchedState]:
        self._check(params)
        obs, _ = self.env.reset(seed=seed_from_key(key))
        self._episodes[:] = 0
        return obs, BatchedState(self._episodes.copy(), np.zeros(self.env.num_envs, np.int32))

    def step(self, key: Any, state: BatchedState, action: Any, params: Any = None) -> Step:
        self._check(params)
        obs, reward, terminated, truncated, infos = self.env.step(action)
        done = terminated | truncated
        self._episodes += done.astype(np.int32)
        iterations = self.env.iterations()
        # Iterations of the episodes that just ended, so a trainer sees them despite the auto-reset.
        ended = infos.get("final_info", {}).get("iterations", 0)
        final_iterations = np.where(done, ended, 0).astype(np.int32)
        info = {"final_iterations": final_iterations, "episode_done": done, "infos": infos}
        return Step(obs, BatchedState(self._episodes.copy(), iterations), reward.astype(np.float32),
                    terminated, truncated, info)
