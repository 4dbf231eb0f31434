"""Run a list of planned episodes (controller, inlet velocity) on a pool of simpleFoam workers.

Each pool slot runs one episode at a time and takes the next planned one when it ends; all running
episodes are stepped together (one batch per step, in parallel over the workers), each with the
action of its own controller. The pool is foam_bridge's local backend, driven directly rather than
through BatchedFoamEnv, for three reasons:

- an episode's velocity is chosen per reset (``options={"inlet_velocity": v}``), where BatchedFoamEnv's
  auto-reset draws it from the config;
- a slot whose episode has ended is not stepped again (BatchedFoamEnv steps every env every time, so a
  finished slot would run a wasted episode while the last ones finish);
- the episode's ``log.simpleFoam`` is read (linear-solver cost, foam_cost) after its last step and
  before its slot is reset, which deletes the episode's case directory.

Every result keeps its episode's steps (``trace``: observation acted on, action, reward, iterations,
residuals), which ``LoadedPolicy.rollout`` turns into its record.

Failures are outcomes: a crashed, diverged or hung solver ends its episode with that outcome and
cause, a dead worker with outcome "crashed" and its cause; nothing raises for them. A config or case
the env rejects (every episode would fail alike) raises a one-line ValueError.
"""

from __future__ import annotations

import math
import shutil
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from foam_bridge.backends import BAD_INPUT_ERRORS, WORKER_DIED, Reply, Request, env_dir, make_backend
from foam_bridge.config import FoamEnvConfig, work_root
from foam_bridge.fields import final_field
from jaxsimrl.evaluation.foam_cost import SolverCost, read_solver_cost

#: The sub-directory of an env directory that holds the running episode's case (FoamCaseEnv's layout).
EPISODE_DIR = "episode"


@dataclass(frozen=True)
class Job:
    """One planned episode; ``uid`` names it uniquely and seeds it (its reset and its controller's
    random draws)."""

    uid: int
    controller: str
    geometry: str
    velocity: float
    sample: int


@dataclass(frozen=True)
class StepRecord:
    """One step of an episode: the observation acted on, the action, and what the step returned
    (reward NaN when the worker could not answer; ``residuals`` are the latest initial residuals)."""

    obs: np.ndarray
    action: np.ndarray
    reward: float
    iterations: int
    residuals: dict[str, float]
    outcome: str


@dataclass(frozen=True)
class EpisodeResult:
    """How one episode ended and what it cost.

    ``wall_time_s``: seconds the episode took on its worker, less the time its paused solver waited
    for the rest of the batch (FoamCaseEnv's ``solver_idle_s``); ``cost``: linear-solver iterations and
    the solver's CPU seconds from its log (None if the log could not be read); ``trace``: every step;
    ``final_u``: the U field the run ended with (only with ``run_episodes(..., fields=True)``; None
    if none was written); ``confirmations``: the episode's convergence checks (FoamEnvConfig.
    confirm_alpha_u; empty without them).
    """

    job: Job
    outcome: str
    cause: str
    iterations: int
    wall_time_s: float
    actions: list[list[float]]
    cost: SolverCost | None
    trace: tuple[StepRecord, ...] = ()
    final_u: np.ndarray | None = None
    confirmations: tuple[dict[str, Any], ...] = ()


@dataclass
class _Running:
    job: Job
    obs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))
    steps: int = 0
    iterations: int = 0
    actions: list[list[float]] = field(default_factory=list)
    trace: list[StepRecord] = field(default_factory=list)
    started: float = field(default_factory=time.monotonic)


def run_episodes(cfg: FoamEnvConfig, jobs: Sequence[Job], controllers: Mapping[str, Any], pool: int,
                 on_result: Callable[[EpisodeResult], None] | None = None,
                 fields: bool = False) -> list[EpisodeResult]:
    """Run every job on ``min(pool, len(jobs))`` workers with ``cfg``; results come back in job order;
    ``fields``: keep each run's final U field (``EpisodeResult.final_u``)."""
    if not jobs:
        return []
    slots = min(pool, len(jobs))
    root, temporary = work_root(cfg, None, prefix="foam_eval_")
    results: dict[int, EpisodeResult] = {}
    try:
        backend = make_backend("local", cfg, slots, slots, root)
        try:
            driver = _Driver(backend, root, controllers, results, on_result or (lambda r: None), fields)
            driver.run(jobs, slots)
        finally:
            backend.close()
    finally:
        if temporary:
            shutil.rmtree(root, ignore_errors=True)
    return [results[job.uid] for job in jobs]


class _Driver:
    """Keeps every slot busy: reset where an episode ended, then step all running episodes together."""

    def __init__(self, backend: Any, root: Any, controllers: Mapping[str, Any], results: dict,
                 on_result: Callable[[EpisodeResult], None], fields: bool = False) -> None:
        self.backend, self.root, self.controllers = backend, root, controllers
        self.results, self.on_result, self.fields = results, on_result, fields
        self.active: dict[int, _Running] = {}

    def run(self, jobs: Sequence[Job], slots: int) -> None:
        queue = deque(jobs)
        while queue or self.active:
            starting = [s for s in range(slots) if s not in self.active][:len(queue)]
            for slot in starting:
                self.active[slot] = _Running(queue.popleft())
            if starting:
                self._reset(starting)
            if self.active:
                self._step(self._actions())

    def _reset(self, slots: list[int]) -> None:
        requests = [Request(s, "reset", {"seed": self.active[s].job.uid,
                                         "options": {"inlet_velocity": self.active[s].job.velocity}})
                    for s in slots]
        for reply in self.backend.run(requests):
            running = self.active[reply.env_id]
            if reply.ok:
                running.obs = np.asarray(reply.value[0], np.float32)
                running.started = time.monotonic()
                self.controllers[running.job.controller].begin(running.job.uid)
            else:
                _raise_if_bad_input(reply)
                self._finish(reply.env_id, "crashed", _cause(reply), None)

    def _actions(self) -> dict[int, np.ndarray]:
        """Each controller acts once for all of its running episodes."""
        actions: dict[int, np.ndarray] = {}
        by_controller: dict[str, list[int]] = {}
        for slot, running in self.active.items():
            by_controller.setdefault(running.job.controller, []).append(slot)
        for name, slots in by_controller.items():
            runs = [self.active[s] for s in slots]
            chosen = self.controllers[name].act([r.job.uid for r in runs], np.stack([r.obs for r in runs]),
                                                [r.steps for r in runs])
            actions.update(zip(slots, np.asarray(chosen, np.float64), strict=True))
        return actions

    def _step(self, actions: dict[int, np.ndarray]) -> None:
        requests = [Request(s, "step", {"action": actions[s]}) for s in self.active]
        for reply in self.backend.run(requests):
            running = self.active[reply.env_id]
            action = actions[reply.env_id]
            running.steps += 1
            running.actions.append([float(a) for a in action])
            if not reply.ok:
                running.trace.append(StepRecord(running.obs, action, math.nan, running.iterations, {},
                                                "crashed"))
                self._finish(reply.env_id, "crashed", _cause(reply), None)
                continue
            obs, reward, terminated, truncated, info = reply.value
            running.trace.append(StepRecord(running.obs, action, float(reward), int(info["iterations"]),
                                            dict(info.get("residuals", {})), info["outcome"]))
            running.obs = np.asarray(obs, np.float32)
            running.iterations = int(info["iterations"])
            if terminated or truncated:
                self._finish(reply.env_id, info["outcome"], info.get("cause", ""), info.get("episode"))

    def _finish(self, slot: int, outcome: str, cause: str, record: dict[str, Any] | None) -> None:
        running = self.active.pop(slot)
        if record is not None:
            wall = float(record["wall_time_s"]) - float(record.get("solver_idle_s", 0.0))
            actions = [list(map(float, a)) for a in record["actions"]]
            iterations = int(record["iterations"])
        else:  # the worker could not report: what the driver saw
            wall, actions = time.monotonic() - running.started, running.actions
            iterations = running.iterations
        case = env_dir(self.root, slot) / EPISODE_DIR
        cost = read_solver_cost(case) if running.steps else None
        final = final_field(case, "U") if self.fields and running.steps else None
        checks = tuple(record.get("confirmations", ())) if record is not None else ()
        result = EpisodeResult(running.job, outcome, cause, iterations, wall, actions, cost,
                               tuple(running.trace), None if final is None else final[1], checks)
        self.controllers[running.job.controller].end(running.job.uid)
        self.results[running.job.uid] = result
        self.on_result(result)


def _cause(reply: Reply) -> str:
    return WORKER_DIED if reply.worker_died else reply.error


def _raise_if_bad_input(reply: Reply) -> None:
    """A case or config the env rejects would fail every episode alike: stop with its one-line message."""
    if reply.kind in BAD_INPUT_ERRORS:
        raise ValueError(reply.error)
