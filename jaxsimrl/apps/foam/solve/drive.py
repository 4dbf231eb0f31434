"""The controlled run: one episode of the bridge in a spawned worker, the policy and the watchdog here.

The solver runs in foam_bridge's local backend (a spawned worker process: no fork of this JAX-loaded
process); this process only acts. Every step's factors and residuals, and the watchdog's decision, are
recorded for the report.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from foam_bridge import BAD_INPUT_ERRORS, FoamEnvConfig, LocalBackend, Request, criterion_distance, factors_of
from jaxsimrl.apps.foam.solve.watchdog import Watchdog, WatchdogSettings


@dataclass
class ControlledRun:
    """What the controlled episode did: outcome, K, its env record, the steps and the fallback events."""

    outcome: str = "crashed"
    cause: str = ""
    iterations: int = 0
    record: dict[str, Any] = field(default_factory=dict)
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
    """Run one episode of ``cfg`` with the actor ``actor(inlet_speed)`` returns (asked for once the worker
    has built the case, so that loading a policy overlaps that), switching to ``fallback`` when the
    watchdog fires. Bad input (the env rejects the case): one-line ValueError. ``cfg``'s case must have
    been checked already (jaxsimrl.apps.foam.solve.settings.solve_config does); ``make_env`` builds the
    worker's env (jaxsimrl.apps.foam.solve.settings.CheckedCase: from that check's build); ``on_step(run)``
    after every step but the episode's last (jaxsimrl.apps.foam.solve.live redraws solve.png; the final report
    draws the last, and a drawing of it here would only delay the report by ~0.4 s)."""
    run = ControlledRun()
    started = time.monotonic()
    backend = LocalBackend(cfg, 1, 1, Path(cfg.work_dir), checked=True, make_env=make_env)
    try:
        reply = backend.run([Request(0, "reset", {"seed": 0})])[0]
        if not reply.ok:
            raise ValueError(reply.error) if reply.kind in BAD_INPUT_ERRORS else RuntimeError(reply.error)
        obs, info = reply.value
        run.inlet_speed = float(info.get("inlet_velocity", float("nan")))
        _loop(backend, Request, cfg, actor(run.inlet_speed), fallback, obs,
              Watchdog(dict(cfg.convergence), watchdog), run, say, on_step or (lambda run: None))
    finally:
        backend.close()
    run.wall_time_s = time.monotonic() - started
    return run


def _loop(backend: Any, request: Any, cfg: FoamEnvConfig, actor: Actor, fallback: list[float], obs: Any,
          dog: Watchdog, run: ControlledRun, say: Callable[[str], None],
          on_step: Callable[[ControlledRun], None]) -> None:
    residuals = None
    while True:
        if dog.fired is None:
            action, source = actor.act(obs, residuals), "controller"
        else:
            action, source = list(fallback), "own factors (watchdog)"
        reply = backend.run([request(0, "step", {"action": np.asarray(action)})])[0]
        factors = factors_of(cfg, action).tolist() if cfg.action_share else action  # what the solver got
        step = {"from_iteration": run.iterations, "action": factors, "source": source}
        if not reply.ok:
            run.outcome, run.cause = "crashed", reply.error or "the worker died"
            run.steps.append({**step, "outcome": "crashed"})
            return
        obs, _, terminated, truncated, info = reply.value
        factors = info.get("factors", factors)  # the env's own word (FoamEnvConfig.freeze_decades holds)
        step["action"] = factors
        run.iterations, run.outcome = int(info["iterations"]), info["outcome"]
        run.cause, residuals = info.get("cause", ""), info["residuals"]
        run.steps.append({**step, "to_iteration": run.iterations, "residuals": residuals,
                          "outcome": run.outcome})
        say(f"  {run.iterations:5d} it  factors {', '.join(f'{a:.3f}' for a in factors)}  ({source})  "
            f"{_residual_text(residuals, dog.criterion)}")
        if terminated or truncated:
            run.record = dict(info.get("episode") or {})
            return
        on_step(run)  # not after the last step: the caller's report follows at once
        reason = dog.check(residuals)
        if reason:
            run.events.append({"kind": "watchdog", "at_iteration": run.iterations, "reason": reason,
                               "then": f"the case's own factors {fallback} from the live fields"})
            say(f"  watchdog at {run.iterations}: {reason}; the case's own factors from here")
