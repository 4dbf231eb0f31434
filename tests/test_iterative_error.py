"""The iterative-error estimator and the settle verdict on histories whose truth is known
(foam_bridge._iterative_error, foam_bridge._settle_verdict)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from foam_bridge._iterative_error import (
    CONVERGED,
    CONVERGING,
    MIN_HISTORY,
    OSCILLATING,
    RANGE_MARGIN,
    TOO_EARLY,
    WANDERING,
    WRITTEN_RESOLUTION,
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
    assert estimate(track_of({n: converging(n) for n in range(5, MIN_HISTORY, 5)})).model == TOO_EARLY
    for end in (MIN_HISTORY, 400, 800):
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


def test_a_two_iteration_cycle_on_a_settled_field_is_its_half_range_with_the_margin() -> None:
    """Sampled every 5 (odd) iterations, a two-iteration cycle flips phase between samples."""
    amplitude = 1e-4 * np.linalg.norm(LIMIT) / np.linalg.norm(MODE)
    track = track_of({n: LIMIT + amplitude * (-1) ** n * MODE for n in range(5, 1001, 5)})
    found = estimate(track)
    assert found.model in (OSCILLATING, WANDERING)
    assert found.error == pytest.approx(RANGE_MARGIN * 1e-4, rel=0.05)
    assert found.as_dict()["margin"] == RANGE_MARGIN


def test_a_periodic_value_sampled_every_iteration_has_its_period() -> None:
    track = QuantityTrack("forces/forces.dat total", max_snapshots=1 << 16)
    for n in range(1, 1001):
        track.add(n, np.asarray([1.0 + 0.01 * math.sin(2 * math.pi * n / 7)]))
    found = estimate(track)
    assert found.model == OSCILLATING and found.period == 7
    assert found.error == pytest.approx(RANGE_MARGIN * 0.01, rel=0.05)


def test_an_unchanging_value_is_converged() -> None:
    track = track_of({n: LIMIT for n in range(5, 401, 5)})
    assert estimate(track).model == CONVERGED and estimate(track).error == 0


def test_a_value_near_zero_is_measured_against_its_floor() -> None:
    track = QuantityTrack("forces/forces.dat side")
    for n in range(1, 400):
        track.add(n, np.asarray([1e-20 * (-1) ** n]), floor=1.0)
    assert estimate(track).error <= 1e-19


def test_a_value_swinging_about_zero_is_measured_against_its_mean_not_its_latest_swing() -> None:
    """Where it settles (the mean, about 0.001: the window's mean, short of whole periods, is off by up to
    a few 1e-4) is what the error is relative to, as the truth is; measured against the latest sample
    (0.051) the swing would read 50x smaller. The floor bounds it."""
    track = QuantityTrack("forceCoeffs/coefficient.dat Cl", max_snapshots=1 << 16)
    for n in range(1, 1011):  # ends on a crest: the latest sample 0.051
        track.add(n, np.asarray([0.001 + 0.05 * math.sin(2 * math.pi * n / 40)]), floor=1e-4)
    found = estimate(track)
    assert found.model == OSCILLATING
    assert 0.5 * RANGE_MARGIN * 0.05 / 0.001 <= found.error <= RANGE_MARGIN * 0.05 / 1e-4


def test_a_written_value_is_never_estimated_below_its_resolution() -> None:
    track = QuantityTrack("probes/p 0", max_snapshots=1 << 16, resolution=WRITTEN_RESOLUTION)
    for n in range(1, 400):
        track.add(n, np.asarray([2.0 + 1e-9 * 0.9 ** n]))
    assert estimate(track).error == WRITTEN_RESOLUTION


def test_a_decay_that_ends_in_the_window_is_judged_by_what_is_left_not_by_its_tail() -> None:
    """A fast decay (1e-2 at iteration 300) onto a small wobble (1e-4): the window (the latest third,
    300-450) still holds the decay's tail; the error is the wobble's (with the margin), not the tail's
    range (5e-3), and at or above the truth."""
    wobble = 1e-4 * np.linalg.norm(LIMIT) / np.linalg.norm(SLOW_MODE)
    decay = 1e-2 * np.linalg.norm(LIMIT) / np.linalg.norm(MODE)
    values = {n: LIMIT + decay * 0.9 ** max(0, n - 300) * MODE + wobble * math.sin(n / 7) * SLOW_MODE
              for n in range(5, 451, 5)}
    found = estimate(track_of(values))
    truth = true_error(values[450])
    assert truth <= found.error <= 3 * RANGE_MARGIN * truth, (found, truth)


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


def test_a_cycle_swinging_about_the_tolerance_still_stops_once_it_holds() -> None:
    """Its estimate is within the tolerance at one check and above it at the next: neither count may
    restart the other's."""
    amplitude = 0.96e-3 / RANGE_MARGIN  # with the margin and the noise, the estimate about the tolerance
    noise = np.random.default_rng(1).normal(scale=0.02 * amplitude, size=3001)
    values = {n: LIMIT * (1 + amplitude * math.sin(2 * math.pi * n / 45) + noise[n])
              for n in range(5, 3001, 5)}
    stop, outcome = feed(values, SettleRule(1e-3))
    assert outcome in (OSCILLATING, SETTLED) and stop < 1000, (stop, outcome)  # 2160 if either restarts


def test_nothing_stops_before_the_minimum_or_on_a_drift() -> None:
    drift = {n: LIMIT * (1 + 1e-3 * n) for n in range(5, 2001, 5)}
    assert feed(drift, SettleRule(1e-3)) == (None, None)
    flat = {n: LIMIT for n in range(5, 2001, 5)}
    stop, outcome = feed(flat, SettleRule(1e-3, min_iterations=300))
    assert outcome == SETTLED and stop >= 300


def test_the_monitor_follows_function_object_values_at_their_written_resolution(tmp_path) -> None:
    from foam_bridge._answer_monitor import AnswerMonitor

    monitor = AnswerMonitor(tmp_path, ["U"])
    assert monitor._track("probes/p 0").resolution == WRITTEN_RESOLUTION
    assert monitor._track("U").resolution == 0.0  # a field is read in binary, at full precision


def _monitored_case(root, times, full, precision=None):
    """A case whose time directories hold the monitor's samples of p (converging, 200 cells) at ``times``
    and a full write (p and phi) at ``full``; its controlDict writes ascii (with ``precision`` digits)."""
    (root / "system").mkdir(parents=True)
    digits = "" if precision is None else f"writePrecision {precision};\n"
    (root / "system" / "controlDict").write_text(f"writeFormat ascii;\n{digits}")
    cells = np.linspace(1.0, 2.0, 200)
    for n in [*times, full]:
        directory = root / str(n)
        directory.mkdir()
        body = "\n".join(repr(float(v)) for v in cells + 0.97 ** n * np.sin(7 * cells))
        (directory / "p").write_text("FoamFile\n{\n    format ascii;\n    class volScalarField;\n}\n"
                                     f"internalField nonuniform List<scalar> 200\n(\n{body}\n);\n")
        if n == full:
            (directory / "phi").write_text("FoamFile\n{\n}\n")
    return root


def test_the_runs_own_last_write_soon_after_a_sample_is_not_a_sample(tmp_path) -> None:
    from foam_bridge._answer_monitor import AnswerMonitor

    case = _monitored_case(tmp_path / "case", range(25, 301, 25), full=309)
    monitor = AnswerMonitor(case, ["p"])
    monitor.poll(309, ended=True)
    assert monitor.tracks["p"].iterations[-1] == 300  # its 9-iteration step would read as a slowdown
    assert monitor.verdict is not None and monitor.verdict.iteration == 300
    assert (case / "309" / "p").is_file()  # the run's own write stays

    short = _monitored_case(tmp_path / "short", range(25, 276, 25), full=281)
    monitor = AnswerMonitor(short, ["p"])
    monitor.poll(281, ended=True)
    assert monitor.verdict is not None and monitor.verdict.estimates["p"].model == TOO_EARLY
    assert monitor.report()["iterative_error"] == {"p": None}  # its start-up: nothing to extrapolate


def test_a_fields_reported_error_is_at_least_the_rounding_of_its_written_digits(tmp_path) -> None:
    from foam_bridge._answer_monitor import AnswerMonitor, written_resolution

    case = _monitored_case(tmp_path / "case", range(25, 401, 25), full=409, precision=8)
    assert written_resolution(case) == pytest.approx(5e-8)
    (case / "system" / "controlDict").write_text("writeFormat binary;\n")
    assert written_resolution(case) == 0.0
    (case / "system" / "controlDict").write_text("writeFormat ascii;\n")
    assert written_resolution(case) == pytest.approx(5e-6)  # OpenFOAM's default writePrecision, 6
    monitor = AnswerMonitor(case, ["p"])
    for n in range(25, 401, 25):  # a field that no longer changes: converged, its computed error 0
        (case / str(n) / "p").write_text((case / "25" / "p").read_text())
    monitor.poll(409, ended=True)
    report = monitor.report()
    assert report["quantities"]["p"]["model"] == CONVERGED
    assert report["quantities"]["p"]["computed_error"] == 0.0
    assert report["iterative_error"]["p"] == pytest.approx(5e-6)
