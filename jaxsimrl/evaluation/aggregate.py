"""Scores of many agents as rliable recommends (Agarwal et al., "Deep RL at the Edge of the Statistical
Precipice", 2021): the interquartile mean (IQM) with a stratified-bootstrap confidence interval, next to
the median and the mean, and a performance profile (the fraction of agents scoring above each threshold).

One task (the Lorenz env), so the scores are one per agent, shaped (agents, 1) for rliable. rliable's own
``aggregate_median`` is the median over tasks of each task's mean, which for one task is the mean; the
median here is the median over the agents, bootstrapped in the same way. rliable's bootstrap draws from
NumPy's global generator (its ``random_state`` argument is not used by the resampling): the draws are
seeded with ``seed`` and the global state is restored afterwards, so the same scores and seed give the
same intervals.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

BOOTSTRAP_REPS = 2000
BOOTSTRAP_SEED = 0
CONFIDENCE = 0.95
PROFILE_POINTS = 101
_KEY = "agents"  # rliable's name for the one "algorithm" of a score dict


@contextlib.contextmanager
def _seeded_numpy(seed: int) -> Iterator[None]:
    """NumPy's global generator seeded with ``seed`` inside the block, as it was after it."""
    saved = np.random.get_state()
    np.random.seed(seed)
    try:
        yield
    finally:
        np.random.set_state(saved)


def _scores(scores: Sequence[float]) -> np.ndarray:
    array = np.asarray(scores, dtype=np.float64).reshape(-1, 1)
    if array.size == 0 or not np.all(np.isfinite(array)):
        raise ValueError(f"aggregate statistics need finite scores, got {list(np.ravel(array))}")
    return array


def _statistics(scores: np.ndarray) -> np.ndarray:
    from rliable import metrics

    return np.array([metrics.aggregate_iqm(scores), np.median(scores), metrics.aggregate_mean(scores)])


def interval_estimates(scores: Sequence[float], reps: int = BOOTSTRAP_REPS, seed: int = BOOTSTRAP_SEED,
                       confidence: float = CONFIDENCE) -> dict[str, Any]:
    """IQM, median and mean of ``scores`` (one per agent), each with its ``confidence`` stratified
    bootstrap interval (percentile method, ``reps`` resamples of the agents, seeded with ``seed``):
    ``{"iqm": {"value", "ci_low", "ci_high"}, "median": ..., "mean": ..., "count", "bootstrap": ...}``."""
    from rliable import library

    array = _scores(scores)
    with _seeded_numpy(seed):
        points, intervals = library.get_interval_estimates({_KEY: array}, _statistics, reps=reps,
                                                           confidence_interval_size=confidence)
    report: dict[str, Any] = {"count": int(array.shape[0]),
                              "bootstrap": {"method": "stratified percentile", "reps": reps, "seed": seed,
                                            "confidence": confidence}}
    for i, name in enumerate(("iqm", "median", "mean")):
        report[name] = {"value": float(points[_KEY][i]), "ci_low": float(intervals[_KEY][0, i]),
                        "ci_high": float(intervals[_KEY][1, i])}
    return report


def performance_profile(scores: Sequence[float], taus: np.ndarray, reps: int = BOOTSTRAP_REPS,
                        seed: int = BOOTSTRAP_SEED) -> tuple[np.ndarray, np.ndarray]:
    """(fraction of agents scoring above each of ``taus``, its (2, len(taus)) bootstrap interval)."""
    from rliable import library

    with _seeded_numpy(seed):
        profiles, intervals = library.create_performance_profile({_KEY: _scores(scores)}, taus, reps=reps)
    return profiles[_KEY], intervals[_KEY]


def plot_performance_profile(path: Path, scores: Sequence[float], label: str = "mean return",
                             reps: int = BOOTSTRAP_REPS, seed: int = BOOTSTRAP_SEED) -> Path:
    """Draw the performance profile of ``scores`` (thresholds from their minimum to their maximum, 95 %
    band) to ``path`` (a PNG) with rliable's plot; returns ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from rliable import plot_utils

    low, high = float(np.min(scores)), float(np.max(scores))
    pad = max(high - low, abs(high), 1.0) * 0.05
    taus = np.linspace(low - pad, high + pad, PROFILE_POINTS)
    profile, band = performance_profile(scores, taus, reps, seed)
    fig, ax = plt.subplots(figsize=(7, 4.5))
    plot_utils.plot_performance_profiles({_KEY: profile}, taus, performance_profile_cis={_KEY: band}, ax=ax,
                                         colors={_KEY: "tab:blue"}, xlabel=f"{label} (tau)",
                                         ylabel=f"fraction of {len(scores)} agents > tau")
    ax.set_title(f"performance profile: {len(scores)} agents, 95 % stratified-bootstrap band")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path
