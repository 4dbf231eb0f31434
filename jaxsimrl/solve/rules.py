"""Relaxation without training: a residual rule, a baseline a learned controller must beat, and the first
controller here for plain-SIMPLE cases.

Both act at the env's step boundaries on what every case has: the initial residuals of its criterion's
fields (``log10(residual / threshold)`` per field, the watchdog's distance; jaxsimrl.solve.watchdog), never
on a learned observation, so they apply to plain SIMPLE and SIMPLEC alike, within the box the case's
algorithm tolerates (foam_bridge.user_case.action_box), starting from the case's own factors.

- :class:`ResidualRule` (after Min & Tao 2007, who adjust the factors every n iterations from the
  residuals): when the run's distance to its criterion (the worst field's decades above its threshold)
  fell over the last step, move each factor a share of the way up to the box's top; when it grew by more
  than a developing flow's transient, a share of the way down to the box's bottom; otherwise hold. A
  first version judged each field alone (raise when every field fell, lower when any grew or stalled):
  on pitzDaily it lowered the factors on the early rise of U's residual and oscillated, 450 iterations
  against the case's own 282.

An online bandit (UCB1 over a few factor triples, one per step of 25 iterations) is not offered yet: on
SIMPLEC tutorials its arms at the box's top gained (T3A 212 iterations, own 269), but one step there grew
a plain-SIMPLE case's residuals by 1.2 decades and the watchdog handed the run to the case's own factors
for good; with safer arms it settled on the case's own factors (pitzDaily 277 against 282). Commit
52f1d9d holds it (with the safer arms).

Their constants are module-level and chosen on the controller issue's training cases (the built-in step
and OpenFOAM's pitzDaily, pitzDailyExptInlet, airFoil2D, backwardFacingStep2D and T3A) only.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from foam_bridge.config import K_OMEGA_ACTION, FoamEnvConfig
from jaxsimrl.solve.watchdog import Watchdog, WatchdogSettings

__all__ = ["INTERVALS", "RULES", "ResidualRule", "RulePolicy"]

#: Iterations between two decisions. 50 leaves 4-6 decisions on a 200-300-iteration case (pitzDaily, T3A)
#: while a step still moves the residuals by more than their iteration-to-iteration noise.
RULE_INTERVAL = 50
#: ResidualRule: the share of the way to the box's top taken after a step of progress ...
RAISE_SHARE = 0.5
#: ... and to its bottom after one in which the residuals grew.
LOWER_SHARE = 0.25
#: The run "progressed" over a step when its distance to the criterion (the worst field's decades above
#: its threshold) fell by more than this ...
NOISE_DECADES = 0.02
#: ... and "grew" when it rose by more than this. Not 0: a developing flow's residuals rise for a while
#: under any factors (pitzDaily's U, iterations 50-100, at its own factors).
GROWTH_DECADES = 0.3


def _distance(residuals: Mapping[str, float], criterion: Mapping[str, float]) -> float:
    """Decades above the criterion of the worst field (the watchdog's distance; NaN if none reported)."""
    return Watchdog(criterion).distance(residuals)


def _clip(action: Sequence[float], low: Sequence[float], high: Sequence[float]) -> list[float]:
    return [min(max(a, lo), hi) for a, lo, hi in zip(action, low, high, strict=True)]


@dataclass
class ResidualRule:
    """Raise the factors while the run's distance to its criterion falls, lower them when it grows (see
    the module docstring). ``criterion``: {field: threshold}; ``own``: the case's factors; ``low``,
    ``high``: its box. ``act`` is jaxsimrl.solve.drive's Actor."""

    criterion: Mapping[str, float]
    own: Sequence[float]
    low: Sequence[float]
    high: Sequence[float]
    _last: float | None = None
    _action: list[float] = field(default_factory=list)

    def act(self, obs: Any, residuals: Mapping[str, float] | None) -> list[float]:
        """The factors of the next step: :meth:`first` before the first step, then :meth:`next`."""
        return self.first() if residuals is None else self.next(residuals)

    def first(self) -> list[float]:
        """The first step's factors: the case's own, in the box."""
        self._action = _clip(self.own, self.low, self.high)
        return list(self._action)

    def next(self, residuals: Mapping[str, float]) -> list[float]:
        """The next step's factors, from the residuals at the end of the step just run."""
        now = _distance(residuals, self.criterion)
        last, self._last = self._last, now
        if last is None or not math.isfinite(now):  # the first step is the start-up transient: hold
            return list(self._action)
        gain = last - now
        if gain > NOISE_DECADES:
            target, share = self.high, RAISE_SHARE
        elif gain < -GROWTH_DECADES:
            target, share = self.low, LOWER_SHARE
        else:
            return list(self._action)
        self._action = _clip([a + share * (t - a) for a, t in zip(self._action, target, strict=True)],
                             self.low, self.high)
        return list(self._action)


#: The rules solve offers (``--controller NAME``), and the step length each decides at.
RULES: dict[str, type[ResidualRule]] = {"residual-rule": ResidualRule}
INTERVALS = {"residual-rule": RULE_INTERVAL}


@dataclass(frozen=True)
class RulePolicy:
    """A rule as solve's controller takes it (a ``Controller.policy``): the MDP it acts in (``env_params``:
    its step length and three actions) and how to build it for a case."""

    name: str

    def __post_init__(self) -> None:
        if self.name not in RULES:
            raise ValueError(f"no rule {self.name!r}; choose one of {', '.join(RULES)}")

    @property
    def env_params(self) -> FoamEnvConfig:
        # three actions: alpha_u, alpha_p and the turbulence fields' factor (pitzDaily's good constant
        # (0.95, 0.9, 0.95) moves all three)
        return FoamEnvConfig(interval=INTERVALS[self.name], relax_k_omega=K_OMEGA_ACTION)

    def provenance(self) -> dict[str, Any]:
        """What solve.json records of the rule: its name, step length and constants."""
        return {"rule": self.name, "interval": INTERVALS[self.name], "raise_share": RAISE_SHARE,
                "lower_share": LOWER_SHARE, "noise_decades": NOISE_DECADES, "growth_decades": GROWTH_DECADES,
                "about": "no training: jaxsimrl.solve.rules"}

    def watchdog(self, settings: WatchdogSettings) -> WatchdogSettings:
        """The watchdog's stall window kept in iterations: it counts steps, calibrated on steps of 100
        iterations, and a rule's steps are shorter (3 steps of 50 would call pitzDaily's early plateau a
        stall)."""
        steps = math.ceil(settings.stall_steps * 100 / INTERVALS[self.name])
        return dataclasses.replace(settings, stall_steps=steps)

    def for_case(self, criterion: Mapping[str, float], own: Sequence[float], low: Sequence[float],
                 high: Sequence[float]) -> ResidualRule:
        """The rule for a case's criterion, own factors and box."""
        return RULES[self.name](criterion, own, low, high)
