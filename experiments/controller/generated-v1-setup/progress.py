# SPDX-License-Identifier: GPL-3.0-or-later
"""A training run on generated cases, episode by episode: each episode's cost over its case's own run's in
the reward's unit (-return / 100: solver CPU seconds with --reward solver-time, else iterations), rolling
medians per algorithm, and a figure (progress.png beside the run's episodes.csv).

    python experiments/controller/generated-v1-setup/progress.py experiments/controller/generated-v1-s0
"""

from __future__ import annotations

import csv
import json
import statistics
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

WINDOW = 200


def main(run: Path) -> None:
    config = json.loads((run / "config.json").read_text())
    family = config["family"]
    unit = "solver CPU" if next(iter(family.values()))["reward"] == "solver-time" else "iterations"
    rows = list(csv.DictReader((run / "episodes.csv").open()))
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for colour, algorithm in (("C0", "SIMPLE"), ("C3", "SIMPLEC")):
        mine = [row for row in rows if family[row["case"]]["simple_variant"] == algorithm]
        cost = [-float(row["return"]) / 100.0 for row in mine]
        rolling = [statistics.median(cost[max(0, k - WINDOW + 1):k + 1]) for k in range(len(cost))]
        ax.plot(range(len(cost)), cost, ".", ms=2, alpha=0.25, color=colour)
        ax.plot(range(len(cost)), rolling, color=colour, label=f"{algorithm}: rolling median of {WINDOW}")
        if cost:
            last = cost[-WINDOW:]
            failed = sum(row["outcome"] != "converged" for row in mine[-WINDOW:])
            print(f"{algorithm}: {len(cost)} episodes; last {len(last)}: median cost "
                  f"{statistics.median(last):.3f}x own {unit}, not converged {failed}")
    ax.axhline(1.0, color="k", lw=0.8, ls="--", label="the case's own settings")
    ax.set(xlabel="episode (of its algorithm)", ylabel=f"{unit} / own run's", ylim=(0, 3),
           title=f"{run.name}: {len(rows)} episodes")
    ax.legend()
    fig.tight_layout()
    fig.savefig(run / "progress.png", dpi=110)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
