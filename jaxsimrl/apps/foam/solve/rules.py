"""Relaxation without training: a residual rule and an online bandit, the baselines a learned controller
must beat, and the first controllers here for plain-SIMPLE cases.

Both act at the env's step boundaries on what every case has: the initial residuals of its criterion's
fields (the run's *distance* to its criterion, the worst field's ``log10(residual / threshold)``, as the
watchdog measures it; jaxsimrl.apps.foam.solve.watchdog), never on a learned observation, so they apply to
plain SIMPLE and SIMPLEC alike, within the box the case's algorithm tolerates
(foam_bridge._user_case.action_box: SIMPLEC [0.2, 0.95], plain SIMPLE [own / 2, 1.25 own]).

What shaped them, measured on the training tutorials (experiments in benchmarks/RESULTS_solve.md):

- *Every change of alpha_u costs a re-convergence*: the face fluxes simpleFoam iterates on depend on the
  momentum matrix's relaxed diagonal, so a new factor is a slightly new discrete problem and the residuals
  jump (airFoil2D, 0.831 -> 0.853 at 0.67 decade from its criterion: p 4.7e-5 -> 1.5e-3 in 5 iterations).
  So both change factors early or not at all: within FREEZE_DECADES of the criterion they hold.
- *A step's residuals judge its factors late and noisily*: a developing flow's residuals rise for a while
  under any factors (pitzDaily's U, iterations 50-150, at its own factors), and a change's own jump reads
  as growth for ~25 iterations. Steps of 25 made the rule revert good raises (airFoil2D 368 iterations
  against 293 with steps of 50); judging each field alone lowered pitzDaily's factors on U's early rise
  (450 iterations against its own 282).
- *SIMPLEC is made for factors near 1* (Van Doormaal & Raithby 1984: its consistent pressure correction
  needs no pressure relaxation), and its box's top corner converged both SIMPLEC tutorials far faster
  than their own factors; plain SIMPLE's top corner (1.25 own, alpha_u + alpha_p > 1) sent
  pitzDailyExptInlet's p from 0.13 to 0.86 in 25 iterations. So the residual rule starts a SIMPLEC case
  at its box's top and a plain-SIMPLE case at its own factors.

- :class:`ResidualRule` (after Min & Tao 2007, who adjust the factors every n iterations from the
  residuals): raise while the run improves on its best distance, go back to the case's own factors for
  good once it is GROWTH_DECADES above it.
- :class:`Bandit` (UCB1, after Khodak et al. 2024, who tune a solver's settings online inside one run):
  arms from the case's own factors to its box's top, one a step, rewarded by the decades gained per 100
  iterations.
- :class:`RandomFactors`: uniform factors in the box at every step (seeded), the floor of the baselines.

Their constants are module-level and chosen on the controller issue's training cases (the built-in step
and OpenFOAM's pitzDaily, pitzDailyExptInlet, airFoil2D, backwardFacingStep2D and T3A) only.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from foam_bridge import K_OMEGA_ACTION, FoamEnvConfig
from jaxsimrl.apps.foam.solve.watchdog import Watchdog

__all__ = ["DEFAULT_RULE", "INTERVALS", "RULES", "Bandit", "GuardedRise", "OwnFactors", "RandomFactors",
           "ResidualRule", "RulePolicy"]

#: Iterations between two decisions of the residual rule. 50 leaves 4-6 decisions on a 200-300-iteration
#: case (pitzDaily, T3A) and outlasts the jump a change of factors makes (~25 iterations): with steps of
#: 25 the rule read that jump as growth and went back (airFoil2D: 368 iterations against 293).
RULE_INTERVAL = 50
#: The bandit's step: shorter, so that it can try its arms on a 200-300-iteration case and still have
#: steps left to play the best one (3 arms tried by iteration 100 of pitzDaily's 282).
BANDIT_INTERVAL = 25
#: ResidualRule: the share of the way to the box's top taken after a step of progress.
RAISE_SHARE = 0.5
#: The run "progressed" over a step when its distance to the criterion (the worst field's decades above
#: its threshold) fell by more than this ...
NOISE_DECADES = 0.02
#: ... and "grew" when it is this far above its best. Not 0: a developing flow's residuals rise for a
#: while under any factors (pitzDaily's U, iterations 50-150, at its own factors).
GROWTH_DECADES = 0.3
#: Within this many decades of its criterion a run's factors are frozen: every change of alpha_u changes
#: the discrete problem the solver iterates on (simpleFoam's face fluxes depend on the momentum matrix's
#: relaxed diagonal), so the residuals jump and the run re-converges. Measured on airFoil2D: raising
#: alpha_u 0.831 -> 0.853 at iteration 250 (0.67 decade from the criterion) sent p from 4.7e-5 to 1.5e-3
#: in 5 iterations and the run never recovered; the raise 0.787 -> 0.831 at 1.9 decades (iteration 150)
#: made a jump of the same size that was gone 50 iterations later.
FREEZE_DECADES = 1.0
#: The bandit's arms: this many points from the case's own factors (arm 0) to its box's top corner.
ARMS = 3


def _distance(residuals: Mapping[str, float], criterion: Mapping[str, float]) -> float:
    """Decades above the criterion of the worst field (the watchdog's distance; NaN if none reported)."""
    return Watchdog(criterion).distance(residuals)


def _clip(action: Sequence[float], low: Sequence[float], high: Sequence[float]) -> list[float]:
    return [min(max(a, lo), hi) for a, lo, hi in zip(action, low, high, strict=True)]


def _toward(start: Sequence[float], end: Sequence[float], share: float) -> list[float]:
    return [a + share * (b - a) for a, b in zip(start, end, strict=True)]


@dataclass
class _Rule:
    """What both rules share: the case's criterion, own factors and box (``criterion``: {field:
    threshold}; ``own``; ``low``, ``high``), the run's distance to its criterion at the last step boundary
    and the factors in force. ``act`` is jaxsimrl.apps.foam.solve.drive's Actor; subclasses decide in
    ``decide``."""

    criterion: Mapping[str, float]
    own: Sequence[float]
    low: Sequence[float]
    high: Sequence[float]
    simplec: bool = False
    _last: float | None = None
    _action: list[float] = field(default_factory=list)

    def start(self) -> list[float]:
        """The first step's factors: the case's own, in the box."""
        return _clip(self.own, self.low, self.high)

    def act(self, obs: Any, residuals: Mapping[str, float] | None) -> list[float]:
        """The factors of the next step: :meth:`start`'s before the first step; then the same while the
        first step's start-up transient gives no measure, or once the run is within FREEZE_DECADES of its
        criterion; else :meth:`decide`'s."""
        if residuals is None:
            self._action = self.start()
            return list(self._action)
        now = _distance(residuals, self.criterion)
        last, self._last = self._last, now
        if last is not None and math.isfinite(now) and now > FREEZE_DECADES:
            self._action = _clip(self.decide(now, last - now), self.low, self.high)
        return list(self._action)

    def decide(self, now: float, gain: float) -> list[float]:
        """The next factors, given the run's distance now and the decades it gained over the step."""
        raise NotImplementedError


@dataclass
class ResidualRule(_Rule):
    """Start a SIMPLEC case at its box's top and a plain-SIMPLE one at its own factors; after a step that
    took the run's distance below its best, move each factor RAISE_SHARE of the way up to the box's top;
    once the distance is GROWTH_DECADES above its best, go back to the case's own factors for good (the
    box's top is not this run's). Otherwise hold. See the module docstring."""

    _best: float = math.inf
    _capped: bool = False

    def start(self) -> list[float]:
        return list(self.high) if self.simplec else super().start()

    def decide(self, now: float, gain: float) -> list[float]:
        self._best = min(self._best, now + gain)  # the step's start (a frozen step's too) counts
        if now < self._best - NOISE_DECADES:
            self._best = now
            return self._action if self._capped else _toward(self._action, self.high, RAISE_SHARE)
        if now > self._best + GROWTH_DECADES and not self._capped:
            self._capped = True
            return _clip(self.own, self.low, self.high)
        return self._action


@dataclass
class Bandit(_Rule):
    """UCB1 over ARMS factor triples on the line from the case's own factors to its box's top corner, one
    arm a step of BANDIT_INTERVAL iterations, rewarded by the decades the run gained per 100 iterations
    over that step: a rate in log space, which a run converging at a steady rate keeps from its first
    step to its last (a raw drop of the residual shrinks with the residual itself), so early and late
    steps weigh alike. Arms are first tried upward from the case's own; a step that grew the residuals by
    more than GROWTH_DECADES removes its arm and every arm above it (a higher factor is the riskier one).
    Within FREEZE_DECADES of the criterion it stops exploring and plays on (see FREEZE_DECADES)."""

    _arm: int = 0
    _pulls: list[int] = field(default_factory=list)
    _total: list[float] = field(default_factory=list)
    _arms: int = ARMS

    def arm(self, k: int) -> list[float]:
        """Arm k's factors: k / (ARMS - 1) of the way from the case's own (in the box) to the box's top."""
        return _toward(_clip(self.own, self.low, self.high), self.high, k / (ARMS - 1))

    def decide(self, now: float, gain: float) -> list[float]:
        if not self._pulls:
            self._pulls, self._total = [0] * ARMS, [0.0] * ARMS
        rate = gain * 100 / BANDIT_INTERVAL
        self._pulls[self._arm] += 1
        self._total[self._arm] += rate
        if gain < -GROWTH_DECADES and self._arm > 0:
            self._arms = min(self._arms, self._arm)
        self._arm = self._choose()
        return self.arm(self._arm)

    def _choose(self) -> int:
        untried = [k for k in range(self._arms) if self._pulls[k] == 0]
        if untried:
            return untried[0]
        n = sum(self._pulls[: self._arms])
        means = [self._total[k] / self._pulls[k] for k in range(self._arms)]
        spread = max(max(means) - min(means), NOISE_DECADES * 100 / BANDIT_INTERVAL)
        scores = [means[k] + spread * math.sqrt(2 * math.log(n) / self._pulls[k]) for k in range(self._arms)]
        return max(range(self._arms), key=scores.__getitem__)


@dataclass
class RandomFactors(_Rule):
    """Factors drawn uniformly in the case's box at every step, the first step's too, from a stream seeded
    by RANDOM_SEED: the floor any controller must clear (issue 35's "random" baseline). Run as the rules
    are (held within FREEZE_DECADES of the criterion, under solve's watchdog), so that it differs from
    them only in what it decides."""

    _stream: random.Random = field(default_factory=lambda: random.Random(RANDOM_SEED))

    def start(self) -> list[float]:
        return self._draw()

    def decide(self, now: float, gain: float) -> list[float]:
        return self._draw()

    def _draw(self) -> list[float]:
        return [self._stream.uniform(lo, hi) for lo, hi in zip(self.low, self.high, strict=True)]


@dataclass
class OwnFactors(_Rule):
    """The case's own factors at every step: ``solve``'s default rule. Every rule that moves the factors
    lost on some development case (experiments/solve-safety/README.md: the residual rule, the bandit,
    GuardedRise, constants at the box's top or half-way), and a change of alpha_u moves the answer the run
    converges to. With the case's own linear solves the default does not step at all: its result is a plain
    run of the case (jaxsimrl.apps.foam.solve.runner); this rule steps it only under ``--solves lean``,
    whose changed linear solves need the controlled run's case."""

    def decide(self, now: float, gain: float) -> list[float]:
        return self.start()


@dataclass
class GuardedRise(_Rule):
    """Raise the factors for the start-up descent only, and hand the final approach to the case's own.

    The first WARMUP_STEPS steps run at the case's own factors (the start-up transient reads the same
    under any factors); then RISE_SHARE of the way up to the box's top while the run keeps setting new
    bests; back to the case's own factors for good, from the live fields, at the first of: the run within
    SWITCH_DECADES of its criterion (own factors converge the user's case, and near the criterion higher
    ones can hover above it: contraction2D and channelRib at half-way hover 0.05-0.5 decade above theirs
    for 3000 iterations, where their own converge in 219 and 534), no new best by NOISE_DECADES in
    HOVER_STEPS steps, or GROWTH_DECADES above its best. ``switched`` says when and why."""

    switched: tuple[int, str] | None = None
    _best: float = math.inf
    _since: int = 0
    _steps: int = 0

    def act(self, obs: Any, residuals: Mapping[str, float] | None) -> list[float]:
        if residuals is None:
            self._action = self.start()
            return list(self._action)
        self._steps += 1
        now = _distance(residuals, self.criterion)
        if self.switched is not None or not math.isfinite(now):
            return list(self._action)
        reason = self._why_back(now)
        if reason is not None:
            self.switched = (self._steps, reason)
            self._action = self.start()
        elif self._steps >= WARMUP_STEPS:
            self._action = _clip(_toward(self.start(), self.high, RISE_SHARE), self.low, self.high)
        return list(self._action)

    def _why_back(self, now: float) -> str | None:
        if now <= SWITCH_DECADES:
            return f"planned: within {SWITCH_DECADES:g} decades of the criterion"
        if now > self._best + GROWTH_DECADES:
            return f"detector: {now - self._best:.2f} decades above its best"
        if now < self._best - NOISE_DECADES:
            self._best, self._since = now, 0
            return None
        self._since += 1
        if self._since >= HOVER_STEPS and self._steps > WARMUP_STEPS:
            return f"detector: no new best in {self._since} steps"
        return None

    def decide(self, now: float, gain: float) -> list[float]:  # act decides (see the class docstring)
        raise NotImplementedError


#: GuardedRise: steps at the case's own factors first (the start-up transient), the share of the way to the
#: box's top it rises by, the distance to the criterion below which the case's own factors take over, and
#: the steps without a new best after which they do.
WARMUP_STEPS = 1
RISE_SHARE = 0.5
SWITCH_DECADES = 1.0
HOVER_STEPS = 3
GUARDED_INTERVAL = 25
#: OwnFactors' step: it decides nothing, so only the live view's redraws and the watchdog's look need one.
OWN_INTERVAL = 100


#: The random baseline's seed: the same draws for every case and every run.
RANDOM_SEED = 0
#: The rules solve offers (``--controller NAME``), and the step length each decides at.
RULES: dict[str, type[_Rule]] = {"own": OwnFactors, "residual-rule": ResidualRule, "bandit": Bandit,
                                 "random": RandomFactors, "guarded": GuardedRise}
INTERVALS = {"own": OWN_INTERVAL, "residual-rule": RULE_INTERVAL, "bandit": BANDIT_INTERVAL,
             "random": RULE_INTERVAL, "guarded": GUARDED_INTERVAL}
#: solve's default controller (jaxsimrl.apps.foam.solve.runner): the case's own factors.
DEFAULT_RULE = "own"


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
        constants = {"noise_decades": NOISE_DECADES, "growth_decades": GROWTH_DECADES,
                     "freeze_decades": FREEZE_DECADES}
        constants.update({"own": {}, "residual-rule": {"raise_share": RAISE_SHARE}, "bandit": {"arms": ARMS},
                          "random": {"seed": RANDOM_SEED},
                          "guarded": {"warmup_steps": WARMUP_STEPS, "rise_share": RISE_SHARE,
                                      "switch_decades": SWITCH_DECADES,
                                      "hover_steps": HOVER_STEPS}}[self.name])
        return {"rule": self.name, "interval": INTERVALS[self.name], **constants,
                "about": "no training: jaxsimrl.apps.foam.solve.rules"}

    def for_case(self, criterion: Mapping[str, float], own: Sequence[float], low: Sequence[float],
                 high: Sequence[float], simplec: bool) -> _Rule:
        """The rule for a case's criterion, own factors, box and algorithm (``simplec``: consistent)."""
        return RULES[self.name](criterion, own, low, high, simplec)
