"""Training curves of a run directory, read from its metrics.jsonl (no JAX needed).

The metrics hold one row per PPO update, with the mean return of the episodes that ended in it and
their count, not each episode's own return. :func:`episode_curve` therefore gives every episode of an
update that update's mean; a moving average over episodes (the paper's window of 5) is exact when
all episodes of an update end together, as they do in the paper's setups (every env runs a whole
number of updates per 4000-step episode, and all envs start together).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from jaxsimrl.runs.run_dir import MetricsLog, Row, RunDir, rows_with_episodes


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


def read_episode_iterations(path: Path) -> np.ndarray | None:
    """The ``iterations`` column of a foam run's episodes.csv (one row per episode), if it has one."""
    import csv

    if not path.is_file():
        return None
    with path.open(newline="") as handle:
        rows = list(csv.DictReader(handle))
    if not rows or "iterations" not in rows[0]:
        return None
    return np.array([float(row["iterations"] or math.nan) for row in rows])


def plot_training_curves(rows: list[Row], path: str | Path, title: str, window: int = 5,
                         episode_iterations: np.ndarray | None = None) -> None:
    """Return, losses, entropy and KL against env steps (plus iterations per episode for a foam run)
    as one PNG at ``path``."""
    from matplotlib.figure import Figure

    from jaxsimrl.evaluation.plots import save_figure

    panels = 4 + (episode_iterations is not None)
    fig = Figure(figsize=(4.2 * panels, 3.8), layout="constrained")
    axes = fig.subplots(1, panels)
    steps = column(rows, "env_steps")
    curve = episode_curve(rows, window)
    axes[0].plot(steps, column(rows, "mean_episode_return"), ".", color="0.6", ms=4, label="per update")
    axes[0].plot(curve.env_steps, curve.moving_average, color="tab:blue", label=f"{window}-episode average")
    axes[0].set_ylabel("mean episode return")
    axes[0].legend(fontsize=8)
    groups = (("policy_loss", "value_loss"), ("entropy",), ("approx_kl", "clip_fraction"))
    for ax, names in zip(axes[1:4], groups, strict=True):
        for name in names:
            ax.plot(steps, column(rows, name), label=name)
        ax.legend(fontsize=8)
    for ax in axes[:4]:
        ax.set_xlabel("env steps")
        ax.ticklabel_format(axis="x", style="sci", scilimits=(0, 0))
        ax.grid(alpha=0.3)
    if episode_iterations is not None:
        axes[4].plot(np.arange(1, len(episode_iterations) + 1), episode_iterations, ".-", ms=3)
        axes[4].set_xlabel("episode")
        axes[4].set_ylabel("solver iterations")
        axes[4].grid(alpha=0.3)
    fig.suptitle(title)
    save_figure(fig, path)
