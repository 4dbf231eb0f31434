"""Run a list of planned episodes (controller, inlet velocity) on a pool of simpleFoam workers.

The pool is foam_bridge's episode pool (:func:`foam_bridge._episodes.run_episodes`): each slot runs
one episode at a time and takes the next planned one when it ends, all running episodes are stepped
together, each with the action of its own controller, and each episode's ``log.simpleFoam`` is read
(linear-solver cost) after its last step. A planned episode is reset with its own inlet velocity
(``options={"inlet_velocity": v}``) and seeded by its uid. This module turns eval-foam's plan (Job:
controller name, geometry, velocity, sample) into the pool's jobs and its runs into EpisodeResults.

Every result keeps its episode's steps (``trace``: observation acted on, action, reward, iterations,
residuals), which ``LoadedPolicy.rollout`` turns into its record.

Failures are outcomes: a crashed, diverged or hung solver ends its episode with that outcome and
cause, a dead worker with outcome "crashed" and its cause; nothing raises for them. A config or case
the env rejects (every episode would fail alike) raises a one-line ValueError.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from foam_bridge import EpisodeJob, EpisodeRun, FoamEnvConfig, SolverCost, StepRecord
from foam_bridge import run_episodes as run_on_pool

__all__ = ["EpisodeResult", "Job", "StepRecord", "run_episodes"]


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


def run_episodes(cfg: FoamEnvConfig, jobs: Sequence[Job], controllers: Mapping[str, Any], pool: int,
                 on_result: Callable[[EpisodeResult], None] | None = None,
                 fields: bool = False) -> list[EpisodeResult]:
    """Run every job on ``min(pool, len(jobs))`` workers with ``cfg``; results come back in job order;
    ``fields``: keep each run's final U field (``EpisodeResult.final_u``)."""
    if not jobs:
        return []
    report = on_result or (lambda result: None)
    planned = [EpisodeJob(job.uid, controllers[job.controller], seed=job.uid,
                          options={"inlet_velocity": job.velocity}, tag=job) for job in jobs]
    runs = run_on_pool(cfg, planned, pool, prefix="foam_eval_", on_result=lambda run: report(_result(run)),
                       fields=fields)
    return [_result(run) for run in runs]


def _result(run: EpisodeRun) -> EpisodeResult:
    """eval-foam's result of one pool run: the episode's own record where it reported, else what the
    pool saw (its wall time less the solver's idle waits, as FoamCaseEnv counts them)."""
    record = run.record
    if record is not None:
        wall, iterations = float(record.wall_time_s) - float(record.solver_idle_s), int(record.iterations)
    else:
        wall, iterations = run.host_wall_s, run.iterations
    checks = tuple(record.confirmations or ()) if record is not None else ()
    return EpisodeResult(run.job.tag, run.outcome, run.cause, iterations, wall, run.actions, run.cost,
                         run.trace, run.final_u, checks)
