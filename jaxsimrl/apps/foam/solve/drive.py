"""The controlled run: one episode of foam_bridge's episode pool (the loop eval-foam, grid-foam and policy
rollouts run on) in a spawned worker, the policy and the watchdog here.

The solver runs in foam_bridge's local backend (a spawned worker process: no fork of this JAX-loaded
process); this process only acts. Every step's factors and residuals, and the watchdog's decision, are
recorded for the report.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from foam_bridge import (
    EpisodeJob,
    EpisodeRecord,
    FoamEnvConfig,
    StatelessController,
    StepRecord,
    criterion_distance,
    factors_of,
    run_episodes,
)
from jaxsimrl.apps.foam.solve.watchdog import Watchdog, WatchdogSettings


@dataclass
class ControlledRun:
    """What the controlled episode did: outcome, K, its env record, the steps and the fallback events."""

    outcome: str = "crashed"
    cause: str = ""
    iterations: int = 0
    record: EpisodeRecord | None = None
    steps: list[dict[str, Any]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    inlet_speed: float = float("nan")
    wall_time_s: float = 0.0


class Actor(Protocol):
    """What sets the factors at each step: ``act(obs, residuals)``, residuals None before the first step
    (a learned policy acts on the observation, jaxsimrl.apps.foam.solve.rules on the residuals)."""

    def act(self, obs: Any, residuals: Mapping[str, float] | None) -> list[float]: ...


class LearnedActor:
    """A trained policy's deterministic action on the observation, its inlet term scaled by ``scale``
    (jaxsimrl.apps.foam.solve.settings.observation_factor); its recurrent state kept from step to step. A
    policy trained with FoamEnvConfig.freeze_decades keeps its last action once the run is within that many
    decades of ``criterion``, as its training env did (here rather than in the env: the watchdog's
    fallback must still reach the solver)."""

    def __init__(self, policy: Any, scale: float, freeze_decades: float | None = None,
                 criterion: Mapping[str, float] | None = None) -> None:
        self.policy, self.scale, self.state = policy, scale, None
        self.freeze_decades, self.criterion = freeze_decades, dict(criterion or {})
        self.last: list[float] | None = None
        self.frozen = False

    def act(self, obs: Any, residuals: Mapping[str, float] | None) -> list[float]:
        near = residuals is not None and self.freeze_decades is not None and (
            criterion_distance(residuals, self.criterion) <= self.freeze_decades)
        self.frozen = self.frozen or near
        if self.frozen and self.last is not None:  # for good, as in training
            return list(self.last)
        seen = np.array(obs, dtype=np.float32)
        seen[0] *= self.scale
        action, self.state = self.policy.act(seen, self.state, deterministic=True)
        self.last = [float(a) for a in np.asarray(action).reshape(-1)]
        return list(self.last)


def _residual_text(residuals: Mapping[str, float], criterion: Mapping[str, float]) -> str:
    """The criterion's fields' residuals at the step's end, as a user reads them ("U 2.1e-04/1e-03")."""
    return "  ".join(f"{name} {residuals[name]:.1e}/{threshold:g}" for name, threshold in criterion.items()
                     if name in residuals)


def drive(cfg: FoamEnvConfig, actor: Callable[[float], Actor], fallback: list[float],
          watchdog: WatchdogSettings, say: Callable[[str], None],
          make_env: Callable[[Any, Path, int], Any] | None = None,
          on_step: Callable[[ControlledRun], None] | None = None) -> ControlledRun:
    """Run one episode of ``cfg`` on foam_bridge's episode pool (one job, one worker) with the actor
    ``actor(inlet_speed)`` returns (asked for once the worker has built the case, so that loading a policy
    overlaps that), switching to ``fallback`` when the watchdog fires. Bad input (the env rejects the case):
    one-line ValueError. ``cfg``'s case must have been checked already
    (jaxsimrl.apps.foam.solve.settings.solve_config does); ``make_env`` builds the worker's env
    (jaxsimrl.apps.foam.solve.settings.CheckedCase: from that check's build); ``on_step(run)`` after every
    step but the episode's last (jaxsimrl.apps.foam.solve.live redraws solve.png; the final report draws the
    last, and a drawing of it here would only delay the report by ~0.4 s)."""
    run = ControlledRun()
    started = time.monotonic()
    steering = _Steering(cfg, actor, fallback, Watchdog(dict(cfg.convergence), watchdog), run, say,
                         on_step or (lambda run: None))
    (episode,) = run_episodes(cfg, [EpisodeJob(0, steering, seed=0)], 1, work_dir=cfg.work_dir,
                              make_env=make_env)
    if episode.record is None and not episode.trace:  # the reset failed: no episode to report
        raise RuntimeError(episode.cause or "the worker died")
    run.outcome, run.cause, run.record = episode.outcome, episode.cause, episode.record
    if math.isnan(episode.trace[-1].reward):  # the worker could not answer the last step
        run.steps.append({"from_iteration": run.iterations, "action": steering.sent,
                          "source": steering.source, "outcome": "crashed"})
    run.wall_time_s = time.monotonic() - started
    return run


class _Steering(StatelessController):
    """solve's controller on the episode pool: the actor's factors until the watchdog fires, the case's
    own after; every step recorded in ``run``, said, and shown to ``on_step`` (but the last)."""

    def __init__(self, cfg: FoamEnvConfig, actor: Callable[[float], Actor], fallback: list[float],
                 dog: Watchdog, run: ControlledRun, say: Callable[[str], None],
                 on_step: Callable[[ControlledRun], None]) -> None:
        self.cfg, self.make_actor, self.fallback, self.dog = cfg, actor, fallback, dog
        self.run, self.say, self.on_step = run, say, on_step
        self.actor: Actor | None = None
        self.residuals: Mapping[str, float] | None = None
        self.source, self.sent = "controller", list(fallback)

    def started(self, uid: int, info: Mapping[str, Any]) -> None:
        self.run.inlet_speed = float(info.get("inlet_velocity", float("nan")))
        self.actor = self.make_actor(self.run.inlet_speed)

    def act(self, uids: Sequence[int], obs: np.ndarray, steps: Sequence[int]) -> np.ndarray:
        if self.dog.fired is None:
            assert self.actor is not None
            action, self.source = self.actor.act(obs[0], self.residuals), "controller"
            self._note_switch()
        else:
            action, self.source = list(self.fallback), "own factors (watchdog)"
        self.sent = factors_of(self.cfg, action).tolist() if self.cfg.action_share else list(action)
        return np.asarray([action], np.float64)

    def _note_switch(self) -> None:
        """A rule that goes back to the case's own factors by itself (rules.GuardedRise: ``switched``, its
        step and why) is recorded once, as the watchdog's fallback is."""
        switched = getattr(self.actor, "switched", None)
        if switched is not None and not any(event["kind"] == "own factors" for event in self.run.events):
            self.run.events.append({"kind": "own factors", "at_iteration": self.run.iterations,
                                    "reason": switched[1], "then": f"the case's own factors {self.fallback}"})

    def observe(self, uid: int, step: StepRecord) -> None:
        """A step that answered (the pool shows no other): record it, say it, watch it."""
        run = self.run
        factors = list(step.factors) if step.factors is not None else self.sent  # the env's own word
        record = {"from_iteration": run.iterations, "action": factors, "source": self.source}
        run.iterations, self.residuals = step.iterations, step.residuals
        run.steps.append({**record, "to_iteration": run.iterations, "residuals": step.residuals,
                          "outcome": step.outcome})
        self.say(f"  {run.iterations:5d} it  factors {', '.join(f'{a:.3f}' for a in factors)}  "
                 f"({self.source})  {_residual_text(step.residuals, self.dog.criterion)}")
        if step.outcome != "running":
            return
        run.outcome = step.outcome
        self.on_step(run)  # not after the last step: the caller's report follows at once
        reason = self.dog.check(step.residuals)
        if reason:
            run.events.append({"kind": "watchdog", "at_iteration": run.iterations, "reason": reason,
                               "then": f"the case's own factors {self.fallback} from the live fields"})
            self.say(f"  watchdog at {run.iterations}: {reason}; the case's own factors from here")
