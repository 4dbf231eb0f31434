"""The foam agent's training curve, as the paper plots it, from a train-foam run's episodes.csv.

    python experiments/foam/plot_training.py experiments/foam/train-mesh05 --out experiments/foam/training.png

Left: SIMPLE iterations per episode and their moving average over the last 100 episodes (the paper's
figure). Right: the relaxation factors the agent took, averaged per update, with their spread.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from jaxsimrl.apps.foam.episodes import MOVING_WINDOW, EpisodeLog  # noqa: E402
from jaxsimrl.evaluation.curves import trailing_mean  # noqa: E402


def plot(run: Path, out: Path) -> None:
    rows = EpisodeLog.load(run / "episodes.csv", 10**9).rows
    if not rows:
        sys.exit(f"plot_training: error: {run}/episodes.csv has no episodes")
    iterations = np.array([r["iterations"] for r in rows])
    updates = sorted({r["update"] for r in rows})
    per_update = {u: np.array([a for r in rows if r["update"] == u for a in r["actions"]]) for u in updates}
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4.2), constrained_layout=True)
    left.plot(iterations, ".", ms=2, alpha=0.35, color="tab:gray", label="episode")
    left.plot(trailing_mean(iterations, MOVING_WINDOW), color="tab:blue", lw=2,
              label=f"moving mean, last {MOVING_WINDOW}")
    left.set(xlabel="episode", ylabel="SIMPLE iterations to converge",
             ylim=(0, np.percentile(iterations, 99.5)),
             title=f"{run.name}: {len(rows)} episodes")
    left.legend()
    for column, name, colour in ((0, "alpha_u", "tab:red"), (1, "alpha_p", "tab:green")):
        mean = np.array([per_update[u][:, column].mean() for u in updates])
        std = np.array([per_update[u][:, column].std() for u in updates])
        right.plot(updates, mean, color=colour, label=f"{name} (mean per update)")
        right.fill_between(updates, mean - std, mean + std, color=colour, alpha=0.15)
    right.axhline(0.95, color="k", ls=":", lw=1, label="box edge 0.95")
    right.set(xlabel="PPO update", ylabel="relaxation factor", ylim=(0.15, 1.0), title="actions taken")
    right.legend(loc="lower right")
    fig.savefig(out, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    plot(args.run, args.out or args.run / "training.png")


if __name__ == "__main__":
    main()
