"""Do no harm: the watchdog that hands a run back to the case's own settings.

A learned controller meets cases it never trained on (other geometries, plain SIMPLE, other turbulence
models), where its factors may stall or blow up a solver that the case's own settings converge. Three
lines of defence, cheapest first:

1. Actions stay in the box the case's algorithm tolerates (foam_bridge._user_case.case_defaults: the
   paper's box for SIMPLEC, ``[own / 2, 1.25 own]`` for plain SIMPLE); the env clips into it.
2. This watchdog, at every step boundary (the solver paused, its fields live): it measures the distance to
   convergence, ``d = max over the criterion's fields of log10(residual / threshold)``. It fires on
   *growth* (``d`` more than ``growth_decades`` above the best seen in the run: the residuals are rising)
   or on a *stall* (the best ``d`` has not improved by ``stall_decades`` in ``stall_steps`` steps). From
   then on the live solver gets the case's own factors: no iteration is lost, the fields go on from where
   they are.
3. A run that fails anyway (crash, divergence, hang) is replaced by a run of the case with its own
   settings from its initial fields (jaxsimrl.apps.foam.solve.own): the result is then exactly the user's own,
   at the cost of the iterations spent before. A run that reaches the iteration budget is not rerun: its
   solver ran sound to the user's own budget (measured on backwardFacingStep2D, whose own settings do
   not meet its own criterion in its 2000 iterations either, a rerun only doubled the cost).

Why residuals and not the observation: the residuals are what convergence is measured in on *any* case,
while the policy's observation is scaled for its training family; a rule on them needs no model of the
case. The thresholds are deliberately loose (a decade of growth, 0.1 decade of progress in 300 iterations
at any interval, see for_interval): healthy runs of the training family gain ~1 decade per 100-200 iterations.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from foam_bridge import criterion_distance


@dataclass(frozen=True)
class WatchdogSettings:
    """When the watchdog fires (see the module docstring); ``enabled`` False: never (for experiments)."""

    growth_decades: float = 1.0
    stall_steps: int = 3
    stall_decades: float = 0.1
    enabled: bool = True


#: The step length (iterations) the settings' stall window is calibrated on.
CALIBRATED_INTERVAL = 100


def for_interval(settings: WatchdogSettings, interval: int) -> WatchdogSettings:
    """The settings for a controller that steps every ``interval`` iterations, the stall window kept in
    iterations: it counts steps, and 3 steps of 25 iterations would call a plateau that the case's own run
    passes through a stall (a learned controller at 25 was handed back within 100-525 iterations on 10 of
    11 heldout-v2 cases, issue 47)."""
    return dataclasses.replace(settings, stall_steps=math.ceil(settings.stall_steps * CALIBRATED_INTERVAL
                                                               / interval))


@dataclass
class Watchdog:
    """Feed it each step's residuals (:meth:`check`); it returns why it fires, once, or None."""

    criterion: Mapping[str, float]
    settings: WatchdogSettings = field(default_factory=WatchdogSettings)
    best: float = math.inf
    since_best: int = 0
    fired: str | None = None

    def distance(self, residuals: Mapping[str, float]) -> float:
        """Decades above the criterion of the worst field (<= 0: every field meets it); NaN if none."""
        return criterion_distance(residuals, self.criterion)

    def check(self, residuals: Mapping[str, float]) -> str | None:
        """The reason to fall back now (only the first time), else None."""
        if self.fired is not None or not self.settings.enabled:
            return None
        now = self.distance(residuals)
        if math.isnan(now):
            return None
        reason = None
        if now > self.best + self.settings.growth_decades:
            reason = (f"residuals grew: {now:.2f} decades above the criterion, best so far {self.best:.2f}")
        elif now < self.best - self.settings.stall_decades:
            self.best, self.since_best = now, 0
        else:
            self.since_best += 1
            self.best = min(self.best, now)
            if self.since_best >= self.settings.stall_steps:
                reason = (f"residuals stalled: no gain of {self.settings.stall_decades:g} decade in "
                          f"{self.since_best} steps (at {now:.2f} decades above the criterion)")
        self.fired = reason
        return reason
