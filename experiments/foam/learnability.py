"""What a learner that only sees the training velocities could reach against the best constant.

    python experiments/foam/learnability.py --out experiments/foam/constant_factors/learnability.png

Reads every grid-foam CSV of the constant-factor landscape at alpha_u 0.95 (full mesh, test criterion,
checked at alpha_u 0.9): ``constant_factors/fine_alpha_p_V*`` and ``fine_alpha_p_sweep/V*`` (h),
``fine_2h_alpha_p_V*`` and ``fine_2h_alpha_p_sweep/V*`` (2h). For each geometry it prints

- the iterations of every alpha_p at every velocity (the landscape the policy has to match);
- each velocity's own best alpha_p;
- for every alpha_p: its mean over the training velocities (35-65 m/s) and its ratio to the best
  constant at each test velocity (25, 50, 75 m/s), and whether it meets the target (<= 1.00x at all
  three);
- the constant a perfect learner of constants would pick from the training velocities alone;
- how well a velocity's best alpha_p is predicted by its two nearest velocities (5-10 m/s away;
  one-sided at the ends): the alpha_p with the fewest iterations summed over the two, and its ratio to
  the best constant at the velocity. Nearest among the training velocities (what a policy trained on
  35-65 m/s could know about 25 and 75 m/s) and nearest among all the velocities measured.

and draws the landscape as a heatmap (velocity x alpha_p) with each velocity's best cell framed and the best
constant's alpha_p starred.
"""

from __future__ import annotations

import argparse
import csv
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

HERE = Path(__file__).parent / "constant_factors"
TEST_VELOCITIES = (25.0, 50.0, 75.0)
TRAIN_RANGE = (35.0, 65.0)  # the paper's training inlet velocities
#: (name, CSV globs, the best single constant's alpha_p used by eval-foam)
GEOMETRIES = (
    ("h", ("fine_alpha_p_V*/grid.csv", "fine_alpha_p_sweep/V*/grid.csv"), 0.875),
    ("2h", ("fine_2h_alpha_p_V*/grid.csv", "fine_2h_alpha_p_sweep/V*/grid.csv"), 0.3),
)
VELOCITY = re.compile(r"V(\d+(?:\.\d+)?)")


def landscape(globs: tuple[str, ...]) -> dict[float, dict[float, int]]:
    """{velocity: {alpha_p: iterations}} of every converged alpha_u-0.95 cell in the CSVs."""
    table: dict[float, dict[float, int]] = {}
    for pattern in globs:
        for path in sorted(HERE.glob(pattern)):
            velocity = float(VELOCITY.search(path.parent.name).group(1))
            with open(path, newline="") as handle:
                for row in csv.DictReader(handle):
                    if row["outcome"] == "converged" and float(row["alpha_u"]) == 0.95:
                        table.setdefault(velocity, {})[float(row["alpha_p"])] = int(row["iterations"])
    return table


def training_mean(table: dict[float, dict[float, int]], alpha_p: float) -> float | None:
    """Mean iterations of ``alpha_p`` over the training velocities; None unless run at all of them."""
    training = [v for v in table if TRAIN_RANGE[0] <= v <= TRAIN_RANGE[1]]
    values = [table[v].get(alpha_p) for v in training]
    return None if not training or None in values else float(np.mean(values))


def report(name: str, table: dict[float, dict[float, int]], best_alpha_p: float) -> None:
    """Print the landscape, each velocity's best, and the constants' test ratios."""
    columns = sorted({a for row in table.values() for a in row})
    print(f"\n## {name} (alpha_u 0.95; best constant alpha_p {best_alpha_p:g})\n")
    print("| V (m/s) | " + " | ".join(f"{a:g}" for a in columns) + " | best |")
    print("|---" * (len(columns) + 2) + "|")
    for v in sorted(table):
        row = table[v]
        best = min(row, key=row.get)
        cells = [("**%d**" if a == best else "%d") % row[a] if a in row else "" for a in columns]
        print(f"| {v:g} | " + " | ".join(cells) + f" | {best:g} |")
    baseline = {v: table[v][best_alpha_p] for v in TEST_VELOCITIES}
    print("\n| alpha_p | mean over 35-65 m/s | " +
          " | ".join(f"ratio at {v:g}" for v in TEST_VELOCITIES) + " | meets <= 1.00x |")
    print("|---" * (len(TEST_VELOCITIES) + 3) + "|")
    picks = {}
    for a in columns:
        mean = training_mean(table, a)
        ratios = [table[v][a] / baseline[v] if a in table[v] else None for v in TEST_VELOCITIES]
        if mean is not None:
            picks[a] = mean
        meets = "" if None in ratios else ("yes" if max(ratios) <= 1.0 else "no")
        shown = " | ".join("" if r is None else f"{r:.3f}" for r in ratios)
        print(f"| {a:g} | {'' if mean is None else f'{mean:.1f}'} | {shown} | {meets} |")
    if picks:
        pick = min(picks, key=picks.get)
        print(f"\nfewest mean iterations over the training velocities: alpha_p {pick:g} ({picks[pick]:.1f})")


def neighbour_pick(table: dict[float, dict[float, int]], v: float, candidates: list[float]) \
        -> tuple[list[float], float | None]:
    """The two velocities of ``candidates`` nearest ``v`` (not ``v``) and the alpha_p they prefer together."""
    others = sorted((u for u in candidates if u != v), key=lambda u: (abs(u - v), u))[:2]
    shared = [a for a in table[v] if len(others) == 2 and all(a in table[u] for u in others)]
    return others, min(shared, key=lambda a: sum(table[u][a] for u in others)) if shared else None


def neighbour_transfer(table: dict[float, dict[float, int]], best_alpha_p: float) -> None:
    """Print, per velocity, the alpha_p its two nearest velocities prefer and its ratio to the constant there:
    nearest among the training velocities (what a policy trained on 35-65 m/s could know), and nearest
    among all measured ones."""
    velocities = sorted(table)
    training = [u for u in velocities if TRAIN_RANGE[0] <= u <= TRAIN_RANGE[1]]
    print("\n| V (m/s) | from training velocities: pick, ratio | from any measured: pick, ratio | own best |")
    print("|---|---|---|---|")
    for v in velocities:
        if best_alpha_p not in table[v]:
            continue
        cells = []
        for candidates in (training, velocities):
            others, pick = neighbour_pick(table, v, candidates)
            cells.append("" if pick is None else f"{pick:g} from {' and '.join(f'{u:g}' for u in others)}, "
                         f"{table[v][pick] / table[v][best_alpha_p]:.3f}")
        own = min(table[v].values()) / table[v][best_alpha_p]
        print(f"| {v:g} | {cells[0]} | {cells[1]} | {own:.3f} |")


def draw(ax: plt.Axes, name: str, table: dict[float, dict[float, int]], best_alpha_p: float) -> None:
    """Heatmap of iterations, velocity x alpha_p; each velocity's best framed, the reference starred."""
    velocities = sorted(table)
    columns = sorted({a for row in table.values() for a in row})
    grid = np.full((len(velocities), len(columns)), np.nan)
    for i, v in enumerate(velocities):
        for j, a in enumerate(columns):
            grid[i, j] = table[v].get(a, np.nan)
    # each row relative to its best constant's cell, so velocities with different costs share a scale
    reference = np.array([table[v].get(best_alpha_p, np.nan) for v in velocities])[:, None]
    image = ax.imshow(grid / reference, origin="lower", aspect="auto", cmap="RdBu_r", vmin=0.85, vmax=1.15)
    for i, v in enumerate(velocities):
        for j in range(len(columns)):
            if np.isfinite(grid[i, j]):
                ax.text(j, i, f"{grid[i, j]:.0f}", ha="center", va="center", fontsize=6)
        best = columns.index(min(table[v], key=table[v].get))
        ax.add_patch(plt.Rectangle((best - 0.5, i - 0.5), 1, 1, fill=False, ec="k", lw=1.5))
    ax.set_xticks(range(len(columns)), [f"{a:g}*" if a == best_alpha_p else f"{a:g}" for a in columns],
                  rotation=90, fontsize=7)
    ax.set_yticks(range(len(velocities)),
                  [f"{v:g} (test)" if v in TEST_VELOCITIES else f"{v:g}" for v in velocities], fontsize=7)
    ax.set(xlabel="alpha_p (alpha_u 0.95)", ylabel="inlet velocity (m/s)",
           title=f"{name}: iterations, coloured by the ratio to the best constant (*); framed: row best")
    ax.title.set_fontsize(8)
    plt.colorbar(image, ax=ax, shrink=0.8)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "learnability.png")
    args = parser.parse_args()
    fig, axes = plt.subplots(1, len(GEOMETRIES), figsize=(14, 5.5), constrained_layout=True)
    for ax, (name, globs, best_alpha_p) in zip(axes, GEOMETRIES, strict=True):
        table = landscape(globs)
        report(name, table, best_alpha_p)
        neighbour_transfer(table, best_alpha_p)
        draw(ax, name, table, best_alpha_p)
    fig.savefig(args.out, dpi=120)
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
