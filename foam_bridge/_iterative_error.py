"""How far a run's answer still is from where it would settle: one monitored quantity's iterative error.

Internal to foam_bridge (its users import from ``foam_bridge`` itself); names here may change.

A quantity is a field the case solves (all its cells and components) or one value of a function object
(a force, a probe, a surface average). Its history is sampled as the run goes (foam_bridge._answer_monitor)
and :func:`estimate` says, at every sample, which model holds and the relative error it implies:

- **converging**: the differences between samples shrink geometrically. The error left is what the future
  differences add up to, extrapolated from the measured contraction rate rho per sample: ``d rho / (1 -
  rho)`` with d the latest difference. The last difference alone understates the error by ``rho / (1 -
  rho)``, which is large exactly when convergence is slow (Eca, Kerkvliet & Toxopeus). The rate comes from
  the two halves of a window of the latest samples (their geometric means), not from two samples, so that a
  small cycle riding on the decay does not fake a rate.
- **oscillating** (a period is found) or **wandering** (none): the window's second half has the mean of its
  first within its own half-range (no trend beyond the fluctuation), or its differences do not decay. The
  answer is then the window's mean and its error half the window's range (ITTC 7.5-03-01-01's iterative
  uncertainty); a cycle shorter than the sample interval shows in the differences, whose half is a floor
  of the half-range. A converging history that reaches a floor (the answer wanders at a level) is
  judged so once the floor holds the window's second half: extrapolating its shallowing decay would
  overstate the error many times.
- **converged**: the samples no longer differ at all (round-off).

All errors are relative: a field's to the L2 norm of its latest sample (over the cells, unweighted, as
foam_bridge._fields.relative_l2), a value's to ``max(|value|, floor)`` with the floor the function object's
scale floor (solve's agreement: a side force of 1e-24 is measured against the row's drag, not itself).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["CONVERGED", "CONVERGING", "MIN_HISTORY", "MODELS", "OSCILLATING", "RANGE_MARGIN", "TOO_EARLY",
           "WANDERING", "WRITTEN_RESOLUTION", "Estimate", "QuantityTrack", "cycle_floor", "estimate",
           "farthest", "mean_and_half_range", "norm", "steady_window", "two_windows"]

CONVERGING = "converging"
OSCILLATING = "oscillating"
WANDERING = "wandering"
CONVERGED = "converged"
TOO_EARLY = "too early"
MODELS = (CONVERGING, OSCILLATING, WANDERING, CONVERGED, TOO_EARLY)

#: Samples a quantity needs before any estimate (a rate from fewer is a guess).
MIN_SAMPLES = 8
#: Iterations of the run before any estimate: a shorter history is its start-up, which says nothing of a
#: slower mode to come. Measured on issue 56's converging cases (fields at their own criterion): runs that
#: stopped within 300 iterations had estimates from 1x to 75x their true error (10th to 90th percentile,
#: 86 % at or above it; simpleCar's tutorial stops at 208, its U 11 % from where it settles, estimated
#: 4.6 %), longer ones from 1.6x to 8.4x (96 %).
MIN_HISTORY = 300
#: The window the model is judged on: the latest third of the run, at least this many samples.
WINDOW_FRACTION, MIN_WINDOW = 1.0 / 3.0, 8
#: Converging when the drift between the window's blocks' means shrinks by at least this factor from one
#: block to the next (and the first drift stands out of the latest block's fluctuation).
CONTRACTION = 0.8
#: The extrapolated error is multiplied by this: the measured rate is a window's average, and a decay that
#: slows down later (a second, slower mode taking over) is under-predicted by it.
SAFETY = 3.0
#: A range model's error and half-range are this multiple of the half-range measured over its window: a
#: wandering answer sweeps further over a longer record than the window holds (issue 56's development
#: cases: the reference runs' last third, up to 4x the window, swept 1.05-2.1x as far as the window did).
RANGE_MARGIN = 2.0
#: Relative differences at or below this are round-off: the quantity no longer changes.
ROUND_OFF = 1e-13
#: The resolution of a function object's written value, relative to it: OpenFOAM writes 6 significant
#: digits (writePrecision), so two values that agree to 1e-5 may still be written a unit apart.
WRITTEN_RESOLUTION = 1e-5
#: A period is a lag whose autocorrelation over the window is at least this.
PERIOD_CORRELATION = 0.5


@dataclass(frozen=True)
class Estimate:
    """One quantity's state at a sample: the model that holds, the relative ``error`` of the latest sample
    from where the run settles (inf while too early), the ``period`` in iterations where one is found, and
    the window's ``half_range`` (relative) and length in iterations."""

    model: str
    error: float
    period: int | None = None
    half_range: float = 0.0
    window: int = 0
    rate: float | None = None  # contraction per iteration, where the converging model holds

    def as_dict(self) -> dict[str, object]:
        data: dict[str, object] = {"model": self.model, "error": _finite(self.error),
                                   "half_range": _finite(self.half_range), "window": self.window}
        if self.period is not None:
            data["period"] = self.period
        if self.rate is not None:
            data["rate_per_iteration"] = self.rate
        if self.model in (OSCILLATING, WANDERING):
            data["margin"] = RANGE_MARGIN  # half_range is the window's times this
        return data


def norm(values: np.ndarray) -> float:
    """The L2 norm of all the values, without BLAS: numpy's norm calls BLAS's dot, whose threads spin
    against the solver's on a busy machine (measured: 0.6 ms for 30,000 values on 2 shared cores, 30x
    this); a few values (a function object's) by math.hypot."""
    flat = np.ravel(values)
    if flat.size <= 9:
        return math.hypot(*flat.tolist())
    return math.sqrt(float(np.einsum("i,i->", flat, flat)))


def farthest(stack: np.ndarray, point: np.ndarray) -> float:
    """The largest L2 distance of a stack's rows (snapshots) from ``point``, in one pass."""
    rows = (stack - point).reshape(len(stack), -1)
    return math.sqrt(float(np.max(np.einsum("ij,ij->i", rows, rows))))


def _finite(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


@dataclass
class QuantityTrack:
    """A quantity's history: every sample's iteration and relative difference from the sample before, and
    snapshots of its values, thinned (every other one dropped) whenever more than ``max_snapshots`` are
    kept, so that they cover the whole run at a coarser and coarser stride. The snapshots are the rows of
    one array, so that a window of them is a view, not a copy."""

    name: str
    max_snapshots: int = 256
    iterations: list[int] = field(default_factory=list)
    differences: list[float] = field(default_factory=list)  # [0] is nan: no sample before the first
    #: A written value's resolution, relative (a function object prints 6 significant digits: two values
    #: that agree to 1e-5 may be written apart); no estimate is below it.
    resolution: float = 0.0
    scale: float = 0.0
    floor: float = 0.0
    _stride: int = 1
    _last: np.ndarray | None = None
    _snapshot_its: list[int] = field(default_factory=list)  # the snapshots' iterations, for bisect
    _rows: np.ndarray | None = None  # the snapshots, the first len(_snapshot_its) rows
    _buffer: np.ndarray | None = None  # add's scratch for the difference from the last sample

    def add(self, iteration: int, value: np.ndarray, floor: float = 0.0) -> None:
        """One sample; ``floor``: the smallest magnitude its relative errors are measured against."""
        value = np.asarray(value, dtype=np.float64)
        self.floor = floor
        self.scale = max(float(norm(value)), floor)
        if self._last is None or self._last.shape != value.shape:
            difference = math.nan
        else:
            difference = _relative(float(norm(np.subtract(value, self._last, out=self._scratch(value)))),
                                   self.scale)
        self.iterations.append(int(iteration))
        self.differences.append(difference)
        self._last = value
        if (len(self.iterations) - 1) % self._stride == 0:
            self._keep(int(iteration), value)

    def _scratch(self, value: np.ndarray) -> np.ndarray:
        """A buffer of ``value``'s shape, kept: a new one per sample costs fresh pages (with the in-place
        thinning of _keep, add took half the time on pitzDaily-sized fields, 12,225 cells)."""
        if self._buffer is None or self._buffer.shape != value.shape:
            self._buffer = np.empty_like(value)
        return self._buffer

    def _keep(self, iteration: int, value: np.ndarray) -> None:
        count = len(self._snapshot_its)
        if self._rows is None or self._rows.shape[1:] != value.shape:  # (a new shape starts afresh)
            self._rows, self._snapshot_its, count = np.empty((8, *value.shape)), [], 0
        elif count == len(self._rows):  # grow as a list does, to one more than the most kept
            grown = np.empty((min(2 * count, self.max_snapshots + 1), *value.shape))
            grown[:count] = self._rows
            self._rows = grown
        self._rows[count] = value
        self._snapshot_its.append(iteration)
        if count + 1 > self.max_snapshots:
            for row in range(1, count // 2 + 1):  # every other row, in place (row 2i is never before i)
                self._rows[row] = self._rows[2 * row]
            self._snapshot_its = self._snapshot_its[::2]
            self._stride *= 2

    def window(self, width: int, end: int | None = None) -> tuple[list[int], np.ndarray]:
        """The iterations and the values (rows of one array, a view) of the snapshots in the ``width``
        iterations up to ``end`` (default the latest sample)."""
        if self._rows is None:
            return [], np.empty((0,))
        span = _span(self._snapshot_its, width, self.iterations[-1] if end is None else end)
        return self._snapshot_its[span], self._rows[span]

    def differences_in(self, width: int, end: int) -> np.ndarray:
        """The finite differences between samples in the ``width`` iterations up to ``end`` ([0.0] if
        there is none)."""
        found = self.differences[_span(self.iterations, width, end)]
        return np.asarray([d for d in found if math.isfinite(d)] or [0.0])

    @property
    def latest(self) -> np.ndarray | None:
        return self._last

    def scale_of(self, answer: np.ndarray) -> float:
        """What an error is relative to where the answer settles at ``answer``: its norm, or the floor
        (a value whose mean is near zero, a side force, is measured against its row, not itself)."""
        return max(float(norm(answer)), self.floor)


def _span(iterations: list[int], width: int, end: int) -> slice:
    """The entries of sorted ``iterations`` in the ``width`` iterations up to ``end``: (end - width, end]."""
    return slice(bisect.bisect_right(iterations, end - width), bisect.bisect_right(iterations, end))


def _relative(norm: float, scale: float) -> float:
    if norm == 0:
        return 0.0
    return norm / scale if scale > 0 else math.inf


def estimate(track: QuantityTrack) -> Estimate:
    """The model that holds for ``track`` now and the error of its latest sample (see the module
    docstring); neither the error nor the half-range is below the track's resolution (a difference the
    written value cannot show)."""
    found = _estimate(track)
    least = track.resolution
    if found.model == TOO_EARLY or (found.error >= least and found.half_range >= least):
        return found
    return Estimate(found.model, max(found.error, least), found.period, max(found.half_range, least),
                    found.window, found.rate)


def _estimate(track: QuantityTrack) -> Estimate:
    if track.iterations[-1] < MIN_HISTORY:  # before any array: every value of a case is asked at each check
        return Estimate(TOO_EARLY, math.inf)
    d = np.asarray(track.differences[1:], dtype=np.float64)
    its = np.asarray(track.iterations[1:], dtype=np.int64)
    if len(d) < MIN_SAMPLES or not np.all(np.isfinite(d)):
        return Estimate(TOO_EARLY, math.inf)
    count = max(MIN_WINDOW, int(math.ceil(WINDOW_FRACTION * len(d))))
    d, its = d[-count:], its[-count:]
    window = int(track.iterations[-1] - its[0]) + 1
    if float(d.max()) <= ROUND_OFF:
        return Estimate(CONVERGED, float(d.max()), window=window)
    half = _half_range(track, window, d)
    blocks = _block_drift(track, window)
    if blocks is not None:
        ratio, step, scale, tail = blocks  # per block: contraction, latest drift; the latest block's range
        # a cycle shorter than the sample interval hides from the block means and the thinned snapshots;
        # every one of the latest differences between samples holds it
        shake = cycle_floor(d) * track.scale / scale
        ahead = SAFETY * step * ratio / (1.0 - ratio)
        if ahead >= shake:
            return Estimate(CONVERGING, ahead + shake, window=window, rate=ratio ** (3.0 / window),
                            half_range=half)
        # the decay has ended inside the window: what is left is the fluctuation of its latest block (the
        # window's whole range would count the decay's tail as a swing)
        half = min(half, max(tail, shake))
    period = _period(track, window)
    half *= RANGE_MARGIN
    return Estimate(OSCILLATING if period else WANDERING, half, period, half, window)


def cycle_floor(d: np.ndarray) -> float:
    """Half the smallest of the latest MIN_WINDOW differences between samples: a cycle faster than the
    sample interval (a two-iteration cycle, sampled every odd number of iterations) keeps them all at its
    full swing, a converging quantity does not."""
    return 0.5 * float(np.min(d[-MIN_WINDOW:]))


def _block_drift(track: QuantityTrack, window: int) -> tuple[float, float, float, float] | None:
    """Aitken's extrapolation on the means of the window's three blocks of snapshots (means, so that a
    cycle or a wander on top of the trend averages out): (the contraction per block, the drift between
    the last two blocks' means relative to the scale, the scale: the latest block mean's, the latest
    block's half-range relative to the scale); None where the
    means do not contract by at least CONTRACTION per block or their first drift does not stand out of the
    latest block's fluctuation (the range model then holds)."""
    values = steady_window(track, window)
    if len(values) < 6:
        return None
    thirds = np.array_split(values, 3)
    means = [block.mean(axis=0) for block in thirds]
    scale = track.scale_of(means[2])
    first = _relative(float(norm(means[1] - means[0])), scale)
    second = _relative(float(norm(means[2] - means[1])), scale)
    shake = _relative(farthest(thirds[2], means[2]), scale)
    if first <= shake or second >= CONTRACTION * first:
        return None
    return max(second / first, ROUND_OFF), second, scale, shake


def _half_range(track: QuantityTrack, window: int, d: np.ndarray) -> float:
    """Half the range of the snapshots in the latest ``window`` iterations (their largest distance from
    their mean), or half the largest difference between samples there (a cycle shorter than the sample
    interval), whichever is larger; relative to the scale of their mean (where the answer settles)."""
    values = steady_window(track, window)
    if not len(values):
        return 0.5 * float(d.max())
    mean, half = mean_and_half_range(values, track)
    return max(half, 0.5 * float(d.max()) * track.scale / track.scale_of(mean))


def mean_and_half_range(stack: np.ndarray, track: QuantityTrack,
                        scale: float | None = None) -> tuple[np.ndarray, float]:
    """(the mean of some of ``track``'s snapshots, stacked, their largest distance from it relative to
    ``scale``, by default the mean's own scale)."""
    mean = stack.mean(axis=0)
    return mean, _relative(farthest(stack, mean), track.scale_of(mean) if scale is None else scale)


def two_windows(stack: np.ndarray, split: int, track: QuantityTrack) -> tuple[
        np.ndarray, float, tuple[np.ndarray, float], tuple[np.ndarray, float]]:
    """Two consecutive windows of ``track``'s snapshots, stacked (rows ``[:split]`` the earlier, ``[split:]``
    the later): (their joint mean, the joint half-range, (the later's mean, its half-range), (the earlier's
    mean, its half-range)), every half-range relative to the joint mean's scale. As mean_and_half_range
    three times, in five passes over the stack instead of eight: each window's distances from its own mean
    come from the joint deviations d (|d - c|^2 = |d|^2 - 2 d.c + |c|^2, c its mean's offset), where the
    differences that matter are those of a steady cycle, the size of d and c alike."""
    before, latest = stack[:split], stack[split:]
    mean_b, mean_a = before.mean(axis=0), latest.mean(axis=0)
    mean = (len(before) * mean_b + len(latest) * mean_a) / len(stack)
    rows = (stack - mean).reshape(len(stack), -1)
    squared = np.einsum("ij,ij->i", rows, rows)
    scale = track.scale_of(mean)
    halves = []
    for part, centre in ((slice(split, None), mean_a), (slice(None, split), mean_b)):
        offset = np.ravel(centre - mean)
        reach = float(np.einsum("i,i->", offset, offset))
        far = squared[part] - 2.0 * np.einsum("ij,j->i", rows[part], offset) + reach
        halves.append(_relative(math.sqrt(max(float(far.max()), 0.0)), scale))
    return mean, _relative(math.sqrt(float(squared.max())), scale), (mean_a, halves[0]), (mean_b, halves[1])


def steady_window(track: QuantityTrack, window: int, end: int | None = None) -> np.ndarray:
    """The snapshots of ``track`` in the ``window`` iterations up to ``end`` (default its latest),
    stacked."""
    return track.window(window, end)[1]


def _period(track: QuantityTrack, window: int) -> int | None:
    """The period, in iterations, of a quantity sampled at a regular stride over ``window``: the first lag
    whose autocorrelation is a local maximum of at least PERIOD_CORRELATION; None where there is none (a
    field sampled less often than it cycles shows no period: its half-range still holds the cycle)."""
    its, stack = track.window(window)
    if len(its) < 6:
        return None
    steps = np.diff(its)
    if np.any(steps != steps[0]):
        return None
    stack = stack.reshape(len(its), -1)
    series = stack[:, 0] if stack.shape[1] == 1 else np.sqrt(np.einsum("ij,ij->i", stack, stack))
    series = series - series.mean()
    lagged = np.correlate(series, series, "full")[len(series) - 1:]  # lag 0, 1, ...: no BLAS
    if lagged[0] <= 0:
        return None
    correlations = list(lagged[1:len(series) // 2] / lagged[0])
    for index in range(1, len(correlations) - 1):
        if correlations[index] >= PERIOD_CORRELATION and correlations[index] >= correlations[index - 1] \
                and correlations[index] >= correlations[index + 1]:
            return int((index + 1) * steps[0])
    return None
