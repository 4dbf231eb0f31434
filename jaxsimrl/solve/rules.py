"""Relaxation without training: a residual rule and an online bandit, the baselines a learned controller
must beat, and the first controllers here for plain-SIMPLE cases.

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
- :class:`Bandit` (after Khodak et al. 2024, who tune a solver's settings online inside one run): three
  factor triples around the case's own (:func:`_bandit_arms`), one chosen per step of 25 iterations by
  UCB1 on a reward that stays comparable from the first step to the last (:meth:`Bandit.reward`). 25:
  a 200-300-iteration case then has 8-12 decisions, enough to try each arm once after the start-up
  step and exploit the best for the rest; shorter steps would score arms on the iteration-to-iteration
  noise of the residuals.

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

__all__ = ["INTERVALS", "RULES", "Bandit", "ResidualRule", "RulePolicy"]

#: Iterations between two decisions. 50 leaves 4-6 decisions on a 200-300-iteration case (pitzDaily, T3A)
#: while a step still moves the residuals by more than their iteration-to-iteration noise.
RULE_INTERVAL = 50
#: The bandit decides more often: it must try each arm before it can exploit one.
BANDIT_INTERVAL = 25
#: ResidualRule: the share of the way to the box's top taken after a step in which every field fell ...
RAISE_SHARE = 0.5
#: ... and to its bottom after one in which a field grew or stalled.
LOWER_SHARE = 0.25
#: The run "progressed" over a step when its distance to the criterion (the worst field's decades above
#: its threshold) fell by more than this ...
NOISE_DECADES = 0.02
#: ... and "grew" when it rose by more than this. Not 0: a developing flow's residuals rise for a while
#: under any factors (pitzDaily's U, iterations 50-100, at its own factors).
GROWTH_DECADES = 0.3
#: UCB1's exploration weight, on rewards normalised to about 1 (Bandit.reward).
UCB_WEIGHT = 0.5


def _distance(residuals: Mapping[str, float], criterion: Mapping[str, float]) -> float:
    """Decades above the criterion of the worst field (the watchdog's distance; NaN if none reported)."""
    return Watchdog(criterion).distance(residuals)


def _clip(action: Sequence[float], low: Sequence[float], high: Sequence[float]) -> list[float]:
    return [min(max(a, lo), hi) for a, lo, hi in zip(action, low, high, strict=True)]


@dataclass
class _Rule:
    """A case's criterion ({field: threshold}), own factors and box; ``act`` is jaxsimrl.solve.drive's
    Actor: ``first()`` before the first step, then ``next(residuals)`` after each."""

    criterion: Mapping[str, float]
    own: Sequence[float]
    low: Sequence[float]
    high: Sequence[float]

    def act(self, obs: Any, residuals: Mapping[str, float] | None) -> list[float]:
        return self.first() if residuals is None else self.next(residuals)

    def first(self) -> list[float]:
        raise NotImplementedError

    def next(self, residuals: Mapping[str, float]) -> list[float]:
        raise NotImplementedError

    def constants(self) -> dict[str, Any]:
        """What the report records of the rule (its provenance)."""
        raise NotImplementedError


@dataclass
class ResidualRule(_Rule):
    """Raise the factors while every residual falls, lower them when one grows or stalls (see the module
    docstring)."""

    name: str = "residual-rule"
    interval: int = RULE_INTERVAL
    _last: float | None = None
    _action: list[float] = field(default_factory=list)

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

    def constants(self) -> dict[str, Any]:
        return {"rule": self.name, "interval": self.interval, "raise_share": RAISE_SHARE,
                "lower_share": LOWER_SHARE, "noise_decades": NOISE_DECADES, "growth_decades": GROWTH_DECADES}


@dataclass
class Bandit(_Rule):
    """UCB1 over a few factor pairs, one per step, rewarded by the residual drop (module docstring)."""

    name: str = "bandit"
    interval: int = BANDIT_INTERVAL
    arms: list[list[float]] = field(default_factory=list)
    pulls: list[int] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    _gains: list[float] = field(default_factory=list)
    _last: float | None = None
    _arm: int = 0

    def __post_init__(self) -> None:
        if not self.arms:
            self.arms = _bandit_arms(self.own, self.low, self.high)
        self.pulls, self.rewards = [0] * len(self.arms), [0.0] * len(self.arms)

    def first(self) -> list[float]:
        self._arm = 0  # the case's own factors first: its first step is the start-up transient
        return list(self.arms[0])

    def next(self, residuals: Mapping[str, float]) -> list[float]:
        distance = _distance(residuals, self.criterion)
        last, self._last = self._last, distance
        if last is not None and math.isfinite(distance) and math.isfinite(last):
            self.pulls[self._arm] += 1
            self.rewards[self._arm] += self.reward(last - distance)
        self._arm = self._choose()
        return list(self.arms[self._arm])

    def reward(self, gain: float) -> float:
        """The step's gain (decades of the worst field's distance to the criterion) over the mean gain of
        all steps so far: a run's gain per step shrinks as it converges, so the raw gain would favour the
        arms tried early; relative to the run's own pace it stays comparable from the first step to the
        last. A step that lost ground scores below 0."""
        self._gains.append(gain)
        scale = sum(abs(g) for g in self._gains) / len(self._gains)
        return gain / scale if scale > 0 else 0.0

    def constants(self) -> dict[str, Any]:
        return {"rule": self.name, "interval": self.interval, "arms": self.arms, "ucb_weight": UCB_WEIGHT,
                "pulls": self.pulls}

    def _choose(self) -> int:
        untried = [arm for arm, pulls in enumerate(self.pulls) if pulls == 0]
        if untried:
            return untried[0]
        total = sum(self.pulls)
        scores = [self.rewards[arm] / pulls + UCB_WEIGHT * math.sqrt(2 * math.log(total) / pulls)
                  for arm, pulls in enumerate(self.pulls)]
        return max(range(len(self.arms)), key=scores.__getitem__)


def _bandit_arms(own: Sequence[float], low: Sequence[float], high: Sequence[float]) -> list[list[float]]:
    """The case's own factors; every factor half-way from them to the box's top; and momentum and
    turbulence half-way up with pressure at its own. Not the box's top corner: one step there grew
    pitzDailyExptInlet's residuals (plain SIMPLE) by 1.2 decades, and the watchdog then handed the run to
    the case's own factors for good, 1.05x its own iterations."""
    own = _clip(own, low, high)
    half = [o + 0.5 * (h - o) for o, h in zip(own, high, strict=True)]
    moderate = [half[0], own[1], *half[2:]]
    arms: list[list[float]] = []
    for arm in (own, half, moderate):
        if not any(all(abs(a - b) < 1e-6 for a, b in zip(arm, seen, strict=True)) for seen in arms):
            arms.append(arm)
    return arms


#: The rules solve offers (``--controller NAME``), and the step length each decides at.
RULES: dict[str, type[_Rule]] = {"residual-rule": ResidualRule, "bandit": Bandit}
INTERVALS = {"residual-rule": RULE_INTERVAL, "bandit": BANDIT_INTERVAL}


@dataclass(frozen=True)
class RulePolicy:
    """A rule as solve's controller takes it (a ``Controller.policy``): the MDP it acts in (``env_params``:
    its step length; the turbulence fields keep the case's own factors) and how to build it for a case."""

    name: str

    def __post_init__(self) -> None:
        if self.name not in RULES:
            raise ValueError(f"no rule {self.name!r}; choose one of {', '.join(RULES)}")

    @property
    def env_params(self) -> FoamEnvConfig:
        # three actions: alpha_u, alpha_p and the turbulence fields' factor (pitzDaily's good constant
        # (0.95, 0.9, 0.95) moves all three)
        return FoamEnvConfig(interval=INTERVALS[self.name], relax_k_omega=K_OMEGA_ACTION)

    def watchdog(self, settings: WatchdogSettings) -> WatchdogSettings:
        """The watchdog's stall window kept in iterations: it counts steps, calibrated on steps of 100
        iterations, and a rule's steps are shorter (3 steps of 25 would call pitzDaily's early plateau a
        stall)."""
        steps = math.ceil(settings.stall_steps * 100 / INTERVALS[self.name])
        return dataclasses.replace(settings, stall_steps=steps)

    def for_case(self, criterion: Mapping[str, float], own: Sequence[float], low: Sequence[float],
                 high: Sequence[float]) -> _Rule:
        """The rule for a case's criterion, own factors and box."""
        return RULES[self.name](criterion, own, low, high)
