"""The foam agent's training with several worker pools (the paper's ``mean_reward_solver``: 4, 8, 16 workers).

    python experiments/paper/fig_foam_pools.py experiments/foam/pool1-mesh05 experiments/foam/train-mesh05 \
        --episodes 400

Each RUN is a train-foam run directory; the runs should differ only in ``--pool`` (and ``--num-envs``,
which follows it). For each run, over its first ``--episodes`` episodes: left, the moving mean of the
SIMPLE iterations over the last 100 episodes against the episode (the paper's curve); right, the same
against the training wall time at the end of each update (from metrics.jsonl), one point per
update. Writes ``--out``/fig_foam_pools.png and fig_foam_pools.json (per run: pool, envs, wall
time to the episode budget, episodes per hour, the final moving mean, the machine's load when it ran).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from jaxsimrl.apps.foam.episodes import MOVING_WINDOW, EpisodeLog
from jaxsimrl.evaluation.curves import read_rows, trailing_mean
from jaxsimrl.runs.atomic import atomic_write_json
from jaxsimrl.runs.run_dir import RunDir


def pool_curve(run_dir: Path, episodes: int) -> dict[str, Any]:
    """The first ``episodes`` episodes of a run: iterations, their moving mean and training wall time."""
    run = RunDir.existing(run_dir)
    record = run.read_config()
    rows = EpisodeLog.load(run.path / "episodes.csv", 10**9).rows[:episodes]
    if not rows:
        raise ValueError(f"{run.path}/episodes.csv has no episodes")
    wall_by_update = {int(r["update"]): float(r["wall_time_s"]) for r in read_rows(run.path)}
    iterations = np.array([r["iterations"] for r in rows], float)
    wall = np.array([wall_by_update.get(int(r["update"]), math.nan) for r in rows])
    return {"run_dir": str(run_dir), "pool": int(record.get("pool", 0)),
            "num_envs": int(record["ppo"]["num_envs"]), "episodes": len(rows), "iterations": iterations,
            "moving": trailing_mean(iterations, MOVING_WINDOW), "wall_s": wall}


def summary(curve: dict[str, Any]) -> dict[str, Any]:
    wall = float(np.nanmax(curve["wall_s"]))
    return {"run_dir": curve["run_dir"], "pool": curve["pool"], "num_envs": curve["num_envs"],
            "episodes": curve["episodes"], "wall_time_s": round(wall, 1),
            "episodes_per_hour": round(curve["episodes"] / wall * 3600, 1),
            "final_moving_mean_iterations": round(float(curve["moving"][-1]), 1),
            "first_100_mean_iterations": round(float(curve["iterations"][:MOVING_WINDOW].mean()), 1)}


def plot(curves: Sequence[dict[str, Any]], path: Path) -> None:
    from matplotlib.figure import Figure

    from jaxsimrl.evaluation.plots import save_figure

    fig = Figure(figsize=(11, 4.2), layout="constrained")
    by_episode, by_time = fig.subplots(1, 2, sharey=True)
    for curve in curves:
        label = f"pool {curve['pool']} ({curve['num_envs']} envs)"
        episode = np.arange(1, curve["episodes"] + 1)
        by_episode.plot(episode, curve["moving"], label=label)
        ends = np.flatnonzero(np.diff(curve["wall_s"], append=np.inf) != 0)  # an update's last episode
        by_time.plot(curve["wall_s"][ends] / 60, curve["moving"][ends], ".-", label=label)
    by_episode.set(xlabel="episode", ylabel=f"SIMPLE iterations, mean of the last {MOVING_WINDOW} episodes")
    by_time.set(xlabel="training wall time (min)")
    for ax in (by_episode, by_time):
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle("train-foam with different worker pools (same config otherwise), on this 2-core machine")
    save_figure(fig, path)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path, metavar="RUN")
    parser.add_argument("--episodes", type=int, default=400, help="episodes of each run to compare")
    parser.add_argument("--out", type=Path, default=Path(__file__).parent)
    args = parser.parse_args(argv)
    try:
        curves = [pool_curve(run, args.episodes) for run in args.runs]
    except ValueError as err:
        parser.error(str(err))
    args.out.mkdir(parents=True, exist_ok=True)
    plot(curves, args.out / "fig_foam_pools.png")
    numbers = [summary(curve) for curve in curves]
    atomic_write_json(args.out / "fig_foam_pools.json", {"episodes": args.episodes, "runs": numbers})
    for row in numbers:
        print(row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
