"""The iterative-error estimator and the settle verdict on histories whose truth is known
(foam_bridge._iterative_error, foam_bridge._settle_verdict)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foam_bridge._iterative_error import (
    CONVERGED,
    CONVERGING,
    OSCILLATING,
    TOO_EARLY,
    WANDERING,
    QuantityTrack,
    estimate,
)
from foam_bridge._settle_verdict import SETTLED, SettleRule, judge

RNG = np.random.default_rng(0)
LIMIT = RNG.normal(size=(500, 3)) + 2.0
MODE = RNG.normal(size=(500, 3))
SLOW_MODE = RNG.normal(size=(500, 3))


def converging(n: int, rate: float = 0.99, slow: float = 0.0) -> np.ndarray:
    """A field converging geometrically to LIMIT (and, with ``slow``, a second, slower mode)."""
    return LIMIT + rate ** n * MODE + slow * 0.999 ** n * SLOW_MODE


def true_error(value: np.ndarray, limit: np.ndarray = LIMIT) -> float:
    return float(np.linalg.norm(value - limit) / np.linalg.norm(limit))


def track_of(values: dict[int, np.ndarray]) -> QuantityTrack:
    track = QuantityTrack("U")
    for n, value in values.items():
        track.add(n, value)
    return track


def test_too_early_then_a_converging_field_extrapolated_within_a_small_factor_above_the_truth() -> None:
    assert estimate(track_of({n: converging(n) for n in range(5, 30, 5)})).model == TOO_EARLY
    for end in (200, 400, 800):
        track = track_of({n: converging(n) for n in range(5, end + 1, 5)})
        found = estimate(track)
        truth = true_error(converging(end))
        assert found.model == CONVERGING
        assert truth <= found.error <= 5 * truth, (end, found, truth)
        assert found.rate == pytest.approx(0.99, abs=1e-2)


def test_the_last_difference_alone_would_understate_a_slow_convergence() -> None:
    """What the issue asks against: d_n is ~rho/(1-rho) below the error when convergence is slow."""
    track = track_of({n: converging(n, rate=0.998) for n in range(5, 1001, 5)})
    truth = true_error(converging(1000, rate=0.998))
    assert track.differences[-1] < truth / 10
    assert estimate(track).error >= truth


def test_a_two_iteration_cycle_on_a_settled_field_is_half_its_range() -> None:
    """Sampled every 5 (odd) iterations, a two-iteration cycle flips phase between samples."""
    amplitude = 1e-4 * np.linalg.norm(LIMIT) / np.linalg.norm(MODE)
    track = track_of({n: LIMIT + amplitude * (-1) ** n * MODE for n in range(5, 1001, 5)})
    found = estimate(track)
    assert found.model in (OSCILLATING, WANDERING)
    assert found.error == pytest.approx(1e-4, rel=0.05)


def test_a_periodic_value_sampled_every_iteration_has_its_period() -> None:
    track = QuantityTrack("forces/forces.dat total", max_snapshots=1 << 16)
    for n in range(1, 1001):
        track.add(n, np.asarray([1.0 + 0.01 * math.sin(2 * math.pi * n / 7)]))
    found = estimate(track)
    assert found.model == OSCILLATING and found.period == 7
    assert found.error == pytest.approx(0.01, rel=0.05)


def test_an_unchanging_value_is_converged() -> None:
    track = track_of({n: LIMIT for n in range(5, 201, 5)})
    assert estimate(track).model == CONVERGED and estimate(track).error == 0


def test_a_value_near_zero_is_measured_against_its_floor() -> None:
    track = QuantityTrack("forces/forces.dat side")
    for n in range(1, 200):
        track.add(n, np.asarray([1e-20 * (-1) ** n]), floor=1.0)
    assert estimate(track).error <= 1e-19


def feed(values: dict[int, np.ndarray], rule: SettleRule) -> tuple[int | None, str | None]:
    """The iteration and outcome of the first stop the verdict calls for, fed sample by sample."""
    tracks = {"U": QuantityTrack("U")}
    since = None
    for n, value in values.items():
        tracks["U"].add(n, value)
        verdict, since = judge(tracks, n, rule, since)
        if verdict.outcome is not None:
            return n, verdict.outcome
    return None, None


def test_settled_stops_once_the_error_is_within_the_tolerance_and_not_far_after() -> None:
    values = {n: converging(n, rate=0.995) for n in range(5, 5001, 5)}
    first = next(n for n in values if all(true_error(values[m]) <= 1e-3 for m in values if m >= n))
    stop, outcome = feed(values, SettleRule(1e-3))
    assert outcome == SETTLED
    assert true_error(values[stop]) <= 1e-3
    assert stop <= 1.5 * first, (stop, first)


def test_an_oscillation_above_the_tolerance_stops_once_its_mean_and_range_hold() -> None:
    values = {n: LIMIT * (1 + 0.01 * math.sin(2 * math.pi * n / 45)) for n in range(5, 3001, 5)}
    stop, outcome = feed(values, SettleRule(1e-3))
    assert outcome == OSCILLATING
    assert stop < 3000


def test_nothing_stops_before_the_minimum_or_on_a_drift() -> None:
    drift = {n: LIMIT * (1 + 1e-3 * n) for n in range(5, 2001, 5)}
    assert feed(drift, SettleRule(1e-3)) == (None, None)
    flat = {n: LIMIT for n in range(5, 2001, 5)}
    stop, outcome = feed(flat, SettleRule(1e-3, min_iterations=300))
    assert outcome == SETTLED and stop >= 300
