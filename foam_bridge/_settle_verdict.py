"""When a run's answer has settled: the verdict over every monitored quantity, and when to stop.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

A run may stop on its answer (the case's own criterion and budget still stop it too):

- **settled**: every quantity's estimated error (foam_bridge._iterative_error) within the tolerance, and
  so at every check for the latest PERSIST_FRACTION of the run (at least PERSIST_MIN iterations): one
  lucky check is not a settled answer;
- **oscillating**: every quantity not within the tolerance oscillates or wanders, and its mean and
  half-range over the latest window agree with the window before (within STABLE of the half-range): more
  iterations only repeat the cycle. Its error is then half its range over both windows.

Nothing stops before MIN_ITERATIONS: a flow still starting up may not have reached a quantity yet (and
nothing is estimated before foam_bridge._iterative_error.MIN_HISTORY, so no stop comes before it either).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from foam_bridge._iterative_error import (
    OSCILLATING,
    RANGE_MARGIN,
    WANDERING,
    Estimate,
    QuantityTrack,
    cycle_floor,
    estimate,
    norm,
    two_windows,
)

__all__ = ["DEFAULT_TOLERANCE", "MIN_ITERATIONS", "SETTLED", "SettleRule", "Verdict", "judge", "judge_due"]

#: The default tolerance of ``--settle``: a relative error of 1e-3 (docs/solve.md says how it was chosen).
DEFAULT_TOLERANCE = 1e-3
SETTLED = "settled"
#: No stop on the answer before this many iterations.
MIN_ITERATIONS = 100
#: A settled verdict must hold over this fraction of the run so far, and at least PERSIST_MIN iterations.
PERSIST_FRACTION, PERSIST_MIN = 0.1, 25
#: An oscillating answer is judged over two windows of this fraction of the run (at least
#: MIN_CYCLE_WINDOW iterations each); its mean and half-range must agree within STABLE of the half-range.
CYCLE_FRACTION, MIN_CYCLE_WINDOW, STABLE = 1.0 / 3.0, 300, 0.25


#: The verdict is judged again once the run has gone this fraction further (at every sample early on):
#: about 35 judgements per run, each a few field operations over the window's snapshots.
JUDGE_FRACTION = 0.03


def judge_due(iteration: int, last: int | None) -> bool:
    """Whether the verdict is due at ``iteration``, the last one judged at ``last`` (None: never)."""
    return last is None or iteration - last >= JUDGE_FRACTION * iteration


@dataclass(frozen=True)
class SettleRule:
    """The tolerance (a relative error) and the earliest iteration a stop on the answer may come."""

    tolerance: float = DEFAULT_TOLERANCE
    min_iterations: int = MIN_ITERATIONS


@dataclass
class Verdict:
    """The state of the answer at ``iteration``: ``outcome`` SETTLED or OSCILLATING when the run should
    stop on it (else None), and every quantity's estimate."""

    iteration: int
    outcome: str | None
    estimates: dict[str, Estimate] = field(default_factory=dict)

    def errors(self) -> dict[str, float | None]:
        """{quantity: estimated relative error} (None while too early to say)."""
        return {name: (e.error if math.isfinite(e.error) else None) for name, e in self.estimates.items()}


@dataclass
class _Since:
    """Since which iteration every check said settled, or (separately) oscillating."""

    settled: int | None = None
    cycling: int | None = None


def judge(tracks: Mapping[str, QuantityTrack], iteration: int, rule: SettleRule,
          since: _Since | None = None) -> tuple[Verdict, _Since]:
    """The verdict at ``iteration`` over ``tracks``; ``since``: the previous call's state (None at the
    first), returned updated for the next call."""
    since = since or _Since()
    estimates = {name: estimate(track) for name, track in tracks.items()}
    within = bool(estimates) and all(e.error <= rule.tolerance for e in estimates.values())
    cycling = {name: _cycle(tracks[name], iteration, e, rule) for name, e in estimates.items()
               if e.error > rule.tolerance}
    # steady: every quantity within the tolerance or a steady cycle (one that swings about the tolerance
    # is one or the other from check to check, and must not restart the count each time)
    steady = bool(estimates) and all(found is not None for found in cycling.values())
    estimates.update({name: found for name, found in cycling.items() if found is not None})
    since.settled = (since.settled if since.settled is not None else iteration) if within else None
    since.cycling = (since.cycling if since.cycling is not None else iteration) if steady else None
    held = max(PERSIST_MIN, PERSIST_FRACTION * iteration)
    outcome = None
    if iteration >= rule.min_iterations:
        if since.settled is not None and iteration - since.settled >= held:
            outcome = SETTLED
        elif since.cycling is not None and iteration - since.cycling >= held and not within:
            outcome = OSCILLATING
    return Verdict(iteration, outcome, estimates), since


def _cycle(track: QuantityTrack, iteration: int, found: Estimate, rule: SettleRule) -> Estimate | None:
    """The quantity's estimate as a settled cycle (its error half its range over two windows), when it
    oscillates or wanders with the same mean and half-range over the latest window and the one before;
    else None."""
    if found.model not in (OSCILLATING, WANDERING) or iteration < rule.min_iterations:
        return None
    width = max(MIN_CYCLE_WINDOW, int(CYCLE_FRACTION * iteration))
    if 2 * width > iteration - track.iterations[0]:
        return None
    its, both = track.window(2 * width, iteration)  # the window before the latest, then the latest
    split = bisect.bisect_right(its, iteration - width)
    if len(its) - split < 3 or split < 3:
        return None
    # the two windows measured alike: against where the cycle sits
    mean, overall, (mean_a, half_a), (mean_b, half_b) = two_windows(both, split, track)
    scale = track.scale_of(mean)
    floors = [cycle_floor(track.differences_in(width, iteration - k * width)) * track.scale / scale
              for k in (0, 1)]
    half_a, half_b = max(half_a, floors[0]), max(half_b, floors[1])
    half = max(half_a, half_b)
    shift = float(norm(mean_a - mean_b)) / scale if scale > 0 else math.inf
    if shift > STABLE * half or abs(half_a - half_b) > STABLE * half:
        return None
    overall = max(RANGE_MARGIN * overall, found.half_range)
    return Estimate(found.model, overall, found.period, overall, 2 * width)

