"""The episode pool: a queue of foam episodes on the local worker pool, each with its own reset and
controller, and what each episode was (typed). grid-foam (foam_bridge._grid), eval-foam and policy
rollouts (jaxsimrl) run on it.

Each pool slot runs one episode at a time and takes the next job of the queue when its episode ends;
all running episodes are stepped together (one batch per step, in parallel over the workers), each
with the action of its own controller. The slots are the envs of a FoamBatchCore
(foam_bridge._batched), the one place where foam_bridge sends resets and steps to solvers, which the
lock-step and asynchronous training batches and their replay drive too; the pool is its third
front-end, beside them rather than one of them, because:

- each job is reset with its own seed and options (e.g. ``{"inlet_velocity": v}``), where the training
  batches' auto-reset draws them from the config and the env's seed stream;
- a slot whose episode has ended is not stepped again (a training batch steps every env it holds, so a
  finished slot would run a wasted episode while the last ones finish);
- the episode's ``log.simpleFoam`` (its linear-solver cost) and, if asked, its final U field are read
  after its last step and before its slot is reset, which deletes the episode's case directory.

A controller is one of:

- an object with ``begin(uid)``, ``act(uids, obs, steps) -> actions`` (one row per episode) and
  ``end(uid)`` (:class:`Controller`); it acts once per step for all running episodes that share it; one
  that also has ``observe(uid, step)`` is shown each :class:`StepRecord` of its episodes (a controller
  that acts on the residuals, not the observation), one that has ``started(uid, info)`` each episode's
  reset info (``jaxsimrl solve`` sizes its observation by the case's inlet speed);
- a callable ``obs -> action`` (one episode's observation, called per episode);
- constant factors (a sequence of floats), the same action at every step.

Failures are outcomes: a crashed, diverged or hung solver ends its episode with that outcome and cause,
a dead worker with outcome "crashed" and :data:`WORKER_DIED` (and the batch core's record of the
episode as far as it got; the step it could not answer has reward NaN); the other jobs go on. A config
or case the env rejects (every episode would fail alike) raises a one-line ValueError.
"""

from __future__ import annotations

import math
import shutil
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from foam_bridge._backends import BAD_INPUT_ERRORS, WORKER_DIED, env_dir
from foam_bridge._batched import FoamBatchCore
from foam_bridge._config import FoamEnvConfig
from foam_bridge._env import EPISODE_DIR
from foam_bridge._fields import final_field
from foam_bridge._logparse import SolverCost, read_solver_cost
from foam_bridge._records import EpisodeRecord
from foam_bridge._work_dirs import work_root

__all__ = ["ConstantFactors", "Controller", "EpisodeJob", "EpisodeRun", "StatelessController", "StepRecord",
           "check_pool", "run_episodes"]


class Controller(Protocol):
    """Acts for a batch of running episodes; ``begin``/``end`` bracket each episode (by its job uid)."""

    def begin(self, uid: int) -> None: ...

    def act(self, uids: Sequence[int], obs: np.ndarray, steps: Sequence[int]) -> np.ndarray: ...

    def end(self, uid: int) -> None: ...


@dataclass(frozen=True)
class EpisodeJob:
    """One queued episode: ``uid`` names it (results, controllers), ``seed`` and ``options`` are its
    reset's, ``controller`` acts in it (see the module docstring); ``tag``: the caller's own data."""

    uid: int
    controller: Any
    seed: int | None = None
    options: Mapping[str, Any] | None = None
    tag: Any = None


@dataclass(frozen=True)
class StepRecord:
    """One step of an episode: the observation acted on, the action, and what the step returned
    (reward NaN when the worker could not answer; ``residuals`` are the latest initial residuals;
    ``factors`` the factors the env says were in force, None where it did not say). The step ended its
    episode when ``outcome`` is not ``"running"``."""

    obs: np.ndarray
    action: np.ndarray
    reward: float
    iterations: int
    residuals: dict[str, float]
    outcome: str
    factors: tuple[float, ...] | None = None


@dataclass(frozen=True)
class EpisodeRun:
    """How one job's episode ended. ``iterations``: K after the last step that answered; ``record``: the
    env's episode record (None when the worker could not report: a failed reset or step);
    ``trace``: every step; ``cost``: linear-solver iterations and CPU seconds from its log (None
    without one); ``final_u``: the U field it ended with (only with ``fields=True``; None if none was
    written); ``host_wall_s``: seconds as this process saw them from the end of its reset (from the
    slot taking the job if the reset failed); ``reset_s``: the reset's seconds (0 if it failed)."""

    job: EpisodeJob
    outcome: str
    cause: str
    iterations: int
    record: EpisodeRecord | None
    trace: tuple[StepRecord, ...]
    cost: SolverCost | None
    final_u: np.ndarray | None
    host_wall_s: float
    reset_s: float

    @property
    def actions(self) -> list[list[float]]:
        """The factors taken: the env's record of them, else those sent."""
        taken = self.record.actions if self.record is not None else [step.action for step in self.trace]
        return [list(map(float, a)) for a in taken]


def check_pool(pool: Any) -> int:
    """``pool`` if it is an integer >= 1; one-line ValueError if not."""
    if isinstance(pool, bool) or not isinstance(pool, int) or pool < 1:
        raise ValueError(f"pool must be an integer >= 1, got {pool!r}")
    return pool


def run_episodes(cfg: FoamEnvConfig, jobs: Sequence[EpisodeJob], pool: int, *,
                 work_dir: str | Path | None = None, prefix: str = "foam_episodes_",
                 keep_temporary: bool = False, on_result: Callable[[EpisodeRun], None] | None = None,
                 fields: bool = False, make_env: Callable[[Any, Path, int], Any] | None = None
                 ) -> list[EpisodeRun]:
    """Run every job on ``min(pool, len(jobs))`` workers with ``cfg``; results come back in job order.
    The env directories go under ``work_dir`` (else ``cfg.work_dir``, else a temporary ``prefix...``
    directory, removed at the end unless ``keep_temporary``); ``on_result`` sees each episode as it
    ends; ``fields``: keep each run's final U field; ``make_env``: how each worker builds its env
    (foam_bridge's backends; None: FoamCaseEnv)."""
    check_pool(pool)
    if not jobs:
        return []
    if len({job.uid for job in jobs}) != len(jobs):
        raise ValueError("jobs: every job needs its own uid")
    slots = min(pool, len(jobs))
    root, temporary = work_root(cfg, work_dir, prefix=prefix)
    results: dict[int, EpisodeRun] = {}
    try:
        with FoamBatchCore(cfg, slots, pool=slots, work_dir=root, make_env=make_env) as batch:
            _Scheduler(batch, root, jobs, results, on_result or (lambda run: None), fields).run(slots)
    finally:
        if temporary and not keep_temporary:
            shutil.rmtree(root, ignore_errors=True)
    return [results[job.uid] for job in jobs]


@dataclass
class _Running:
    job: EpisodeJob
    controller: Controller
    obs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))
    steps: int = 0
    iterations: int = 0
    trace: list[StepRecord] = field(default_factory=list)
    started: float = field(default_factory=time.monotonic)
    reset_s: float = 0.0


class _Scheduler:
    """Keeps every slot busy: reset where an episode ended, then step all running episodes together, on
    the batch core that every foam batch drives its solvers through (foam_bridge._batched.FoamBatchCore,
    one env per slot: its resets with each job's own seed and options, its steps only for the slots that
    run an episode, its fault handling)."""

    def __init__(self, batch: FoamBatchCore, root: Path, jobs: Sequence[EpisodeJob],
                 results: dict[int, EpisodeRun], on_result: Callable[[EpisodeRun], None],
                 fields: bool) -> None:
        self.batch, self.root, self.results = batch, root, results
        self.on_result, self.fields = on_result, fields
        self.controllers = _controllers(jobs)
        self.queue = deque(jobs)
        self.active: dict[int, _Running] = {}

    def run(self, slots: int) -> None:
        while self.queue or self.active:
            starting = [s for s in range(slots) if s not in self.active][:len(self.queue)]
            for slot in starting:
                job = self.queue.popleft()
                self.active[slot] = _Running(job, self.controllers[id(job.controller)])
            if starting:
                self._reset(starting)
            if self.active:
                self._step(self._actions())

    def _reset(self, slots: list[int]) -> None:
        jobs = {s: self.active[s].job for s in slots}
        started, failures = self.batch.run_resets({s: job.seed for s, job in jobs.items()},
                                                   {s: job.options for s, job in jobs.items()})
        for slot, reply in sorted(failures.items()):
            if reply.kind in BAD_INPUT_ERRORS:  # every episode would fail alike: stop, say why
                raise ValueError(reply.error)
            self._finish(slot, "crashed", reply.error or WORKER_DIED, None)
        for slot, (obs, info) in sorted(started.items()):
            running = self.active[slot]
            running.obs = obs
            now = time.monotonic()
            running.reset_s, running.started = now - running.started, now
            running.controller.begin(running.job.uid)
            if hasattr(running.controller, "started"):
                running.controller.started(running.job.uid, info)

    def _actions(self) -> dict[int, np.ndarray]:
        """Each controller acts once for all of its running episodes."""
        groups: dict[int, list[int]] = {}
        for slot, running in self.active.items():
            groups.setdefault(id(running.controller), []).append(slot)
        actions: dict[int, np.ndarray] = {}
        for slots in groups.values():
            runs = [self.active[s] for s in slots]
            chosen = runs[0].controller.act([r.job.uid for r in runs], np.stack([r.obs for r in runs]),
                                            [r.steps for r in runs])
            actions.update(zip(slots, np.asarray(chosen, np.float64), strict=True))
        return actions

    def _step(self, actions: dict[int, np.ndarray]) -> None:
        results, unanswered = self.batch.run_steps(actions)
        for slot, (obs, reward, terminated, truncated, info) in sorted(results.items()):
            running = self.active[slot]
            running.steps += 1
            factors = info.get("factors")
            # a step the solver's side could not answer has no reward of its own (the batch's is the
            # training penalty): NaN says so to solve's report
            running.trace.append(StepRecord(
                running.obs, actions[slot], math.nan if slot in unanswered else float(reward),
                int(info["iterations"]), dict(info.get("residuals", {})), info["outcome"],
                None if factors is None else tuple(map(float, factors))))
            if hasattr(running.controller, "observe") and slot not in unanswered:
                running.controller.observe(running.job.uid, running.trace[-1])
            running.obs = np.asarray(obs, np.float32)
            running.iterations = int(info["iterations"])
            if terminated or truncated:
                record = info.get("episode")
                self._finish(slot, info["outcome"], info.get("cause", ""),
                             EpisodeRecord.from_json(record) if isinstance(record, Mapping) else None)

    def _finish(self, slot: int, outcome: str, cause: str, record: EpisodeRecord | None) -> None:
        running = self.active.pop(slot)
        case = env_dir(self.root, slot) / EPISODE_DIR
        cost = read_solver_cost(case) if running.steps else None
        final = final_field(case, "U") if self.fields and running.steps else None
        result = EpisodeRun(running.job, outcome, cause, running.iterations, record, tuple(running.trace),
                            cost, None if final is None else final[1], time.monotonic() - running.started,
                            running.reset_s)
        running.controller.end(running.job.uid)
        self.results[running.job.uid] = result
        self.on_result(result)


def _controllers(jobs: Sequence[EpisodeJob]) -> dict[int, Controller]:
    """Each job's controller as a Controller, keyed by the id of what the job gave (jobs that share one
    object share its Controller, which then acts for them together)."""
    made: dict[int, Controller] = {}
    for job in jobs:
        spec = job.controller
        if id(spec) not in made:
            if all(hasattr(spec, name) for name in ("begin", "act", "end")):
                made[id(spec)] = spec
            elif callable(spec):
                made[id(spec)] = _PerEpisode(spec)
            else:
                made[id(spec)] = ConstantFactors(spec)
    return made


class StatelessController:
    """Base of controllers that keep nothing per episode: ``begin`` and ``end`` do nothing."""

    def begin(self, uid: int) -> None:
        pass

    def end(self, uid: int) -> None:
        pass


class ConstantFactors(StatelessController):
    """The same factors at every step."""

    def __init__(self, factors: Sequence[float]) -> None:
        self.factors = np.asarray(factors, np.float64).reshape(-1)

    def act(self, uids: Sequence[int], obs: np.ndarray, steps: Sequence[int]) -> np.ndarray:
        return np.tile(self.factors, (len(uids), 1))


class _PerEpisode(StatelessController):
    """A callable ``obs -> action``, asked once per running episode."""

    def __init__(self, policy: Callable[[np.ndarray], Any]) -> None:
        self.policy = policy

    def act(self, uids: Sequence[int], obs: np.ndarray, steps: Sequence[int]) -> np.ndarray:
        return np.stack([np.asarray(self.policy(row), np.float64).reshape(-1) for row in obs])
