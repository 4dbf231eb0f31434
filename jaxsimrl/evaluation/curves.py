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
    sums = np.cumsum(np.concatenate([[0.0], returns]))
    index = np.arange(1, len(returns) + 1)
    first = np.maximum(index - window, 0)
    average = (sums[index] - sums[first]) / (index - first) if len(returns) else returns
    return EpisodeCurve(index, steps, returns, average)


def column(rows: list[Row], name: str) -> np.ndarray:
    """One metric over the updates as floats (NaN where a row lacks it or holds null)."""
    values = [row.get(name) for row in rows]
    return np.array([math.nan if v is None else float(v) for v in values])
