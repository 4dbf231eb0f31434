"""Training curves of a run directory, read from its metrics.jsonl (no JAX needed).

The metrics hold one row per PPO update, with the mean return of the episodes that ended in it and
their count, not each episode's own return. :func:`episode_curve` therefore gives every episode of an
update that update's mean; a moving average over episodes (the paper's window of 5) is exact when
all episodes of an update end together, as they do in the paper's setups (every env runs a whole
number of updates per 4000-step episode, and all envs start together).
"""

from __future__ import annotations

import math
from collections.abc import Collection
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from jaxsimrl.runs.run_dir import MetricsLog, Row, RunDir, agent_rows, rows_with_episodes

#: The moving window over episodes of a host-env run's iterations (the paper's Fig. 9 uses 100).
MOVING_WINDOW = 100


class EpisodeIterations(NamedTuple):
    """Solver iterations per episode of a host-env run (episodes.csv), and which episodes failed."""

    iterations: np.ndarray  # (E,) iterations run; for a failed episode, where the solver stopped
    failed: np.ndarray  # (E,) bool: its outcome is one of its application's failed_outcomes


class EpisodeCurve(NamedTuple):
    episode: np.ndarray  # (E,) 1-based index of each ended episode
    env_steps: np.ndarray  # (E,) env steps (all envs together) when it ended
    episode_return: np.ndarray  # (E,) its update's mean episode return
    moving_average: np.ndarray  # (E,) mean over the last ``window`` episodes (fewer at the start)


def read_rows(run_dir: str | Path) -> list[Row]:
    """The metrics rows of a run directory; a one-line ValueError if it has none."""
    run = RunDir.existing(run_dir)
    rows = MetricsLog.load(run, math.inf).rows
    if not rows:
        raise ValueError(f"{run.path} has no metrics rows yet ({run.metrics_jsonl.name} missing or empty)")
    return rows


def episode_curve(rows: list[Row], window: int = 5) -> EpisodeCurve:
    """Per-episode returns (each update's mean for its episodes) and their moving average."""
    ended = rows_with_episodes(rows)
    counts = np.array([int(r["episodes"]) for r in ended], dtype=int)
    returns = np.repeat([float(r["mean_episode_return"]) for r in ended], counts)
    steps = np.repeat([int(r["env_steps"]) for r in ended], counts)
    return EpisodeCurve(np.arange(1, len(returns) + 1), steps, returns, trailing_mean(returns, window))


def trailing_mean(values: np.ndarray, window: int) -> np.ndarray:
    """The mean of the last ``window`` values at every index (of all of them before the first window)."""
    values = np.asarray(values, float)
    sums = np.cumsum(np.concatenate([[0.0], values]))
    index = np.arange(1, len(values) + 1)
    first = np.maximum(index - window, 0)
    return (sums[index] - sums[first]) / (index - first) if len(values) else values


def column(rows: list[Row], name: str) -> np.ndarray:
    """One metric over the updates as floats (NaN where a row lacks it or holds null)."""
    values = [row.get(name) for row in rows]
    return np.array([math.nan if v is None else float(v) for v in values])


def _draw_returns(ax: Any, rows: list[Row], steps: np.ndarray, window: int) -> None:
    """One agent's mean return per update (dots) and its ``window``-episode moving average."""
    curve = episode_curve(rows, window)
    ax.plot(steps, column(rows, "mean_episode_return"), ".", color="0.6", ms=4, label="per update")
    ax.plot(curve.env_steps, curve.moving_average, color="tab:blue", label=f"{window}-episode average")


def agent_columns(rows: list[Row], name: str) -> np.ndarray:
    """One metric of a batch run (rows with an ``agent`` column) as (updates, agents) floats."""
    return np.stack([column(own, name) for own in agent_rows(rows).values()], axis=1)


def draw_band(ax: Any, steps: np.ndarray, values: np.ndarray, label: str) -> None:
    """``values`` (updates, agents) as the mean across agents (the agents that have a value) with a band
    from the lowest to the highest agent."""
    import warnings

    with warnings.catch_warnings():  # an update where no agent has a value (no episode ended) stays NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        mean, low, high = (np.nanmean(values, 1), np.nanmin(values, 1), np.nanmax(values, 1))
    (line,) = ax.plot(steps, mean, label=f"{label}: mean of {values.shape[1]} agents (band: min-max)")
    ax.fill_between(steps, low, high, color=line.get_color(), alpha=0.25, linewidth=0)


def read_episode_iterations(path: Path, failed: Collection[str] = ()) -> EpisodeIterations | None:
    """The ``iterations`` of a run's episodes.csv (one row per episode), if it has them, and which rows
    have an ``outcome`` among ``failed`` (a file without an outcome column counts no failure)."""
    import csv

    if not path.is_file():
        return None
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    if not rows or "iterations" not in rows[0]:
        return None
    return EpisodeIterations(np.array([float(row["iterations"] or math.nan) for row in rows]),
                             np.array([row.get("outcome") in failed for row in rows], dtype=bool))


def plot_training_curves(rows: list[Row], path: str | Path, title: str, window: int = 5,
                         episode_iterations: EpisodeIterations | None = None) -> None:
    """Return, losses, entropy and KL against env steps (plus iterations per episode for a host-env run)
    as one PNG at ``path``."""
    from matplotlib.figure import Figure

    from jaxsimrl.evaluation.plots import save_figure

    panels = 4 + (episode_iterations is not None)
    fig = Figure(figsize=(4.2 * panels, 3.8), layout="constrained")
    axes = fig.subplots(1, panels)
    batch = "agent" in rows[0]  # a --seeds run: every metric is drawn as its mean across agents and a band
    steps = column(next(iter(agent_rows(rows).values())) if batch else rows, "env_steps")
    if batch:
        draw_band(axes[0], steps, agent_columns(rows, "mean_episode_return"), "per update")
    else:
        _draw_returns(axes[0], rows, steps, window)
    axes[0].set_ylabel("mean episode return")
    axes[0].legend(fontsize=8)
    groups = (("policy_loss", "value_loss"), ("entropy",), ("approx_kl", "clip_fraction"))
    for ax, names in zip(axes[1:4], groups, strict=True):
        for name in names:
            if batch:
                draw_band(ax, steps, agent_columns(rows, name), name)
            else:
                ax.plot(steps, column(rows, name), label=name)
        ax.legend(fontsize=8)
    for ax in axes[:4]:
        ax.set_xlabel("env steps")
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
        ax.grid(alpha=0.3)
    if episode_iterations is not None:
        plot_episode_iterations(axes[4], episode_iterations)
    fig.suptitle(title)
    save_figure(fig, path)


def plot_episode_iterations(ax: Any, episodes: EpisodeIterations, window: int = MOVING_WINDOW) -> None:
    """Iterations per episode: those that ended well as grey dots with their ``window``-episode moving
    mean, failed ones as red crosses where the solver stopped, left out of the mean (a case that crashes at
    iteration 1 every time must not read as one that converges at once)."""
    index = np.arange(1, len(episodes.iterations) + 1)
    ok, failed = ~episodes.failed, episodes.failed
    ax.plot(index[ok], episodes.iterations[ok], ".", color="0.6", ms=3, label="episode")
    if ok.any():
        ax.plot(index[ok], trailing_mean(episodes.iterations[ok], window), color="tab:blue",
                label=f"{window}-episode mean (failures left out)")
    if failed.any():
        ax.plot(index[failed], episodes.iterations[failed], "x", color="tab:red", ms=5,
                label=f"failed ({int(failed.sum())} of {len(index)}): where the solver stopped")
    ax.set_xlabel("episode")
    ax.set_ylabel("solver iterations")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
