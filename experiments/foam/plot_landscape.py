"""SIMPLE iterations against a constant alpha_p (alpha_u 0.95), one line per inlet velocity (grid-foam CSVs).

    python experiments/foam/plot_landscape.py --out experiments/foam/constant_factors/fine_alpha_p.png

Reads ``constant_factors/fine_alpha_p_V{25,50,75}*/grid.csv`` (full mesh, test criterion, checked at
alpha_u 0.9) and marks the single best constant's alpha_p (0.875) and each velocity's own best.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = Path(__file__).parent / "constant_factors"
BEST_CONSTANT_ALPHA_P = 0.875


def landscape(velocity: int) -> list[tuple[float, int]]:
    """(alpha_p, iterations) of every converged cell at ``velocity``, sorted by alpha_p."""
    points = {}
    for path in sorted(HERE.glob(f"fine_alpha_p_V{velocity}*/grid.csv")):
        with open(path, newline="") as handle:
            for row in csv.DictReader(handle):
                if row["outcome"] == "converged" and float(row["alpha_u"]) == 0.95:
                    points[float(row["alpha_p"])] = int(row["iterations"])
    return sorted(points.items())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "fine_alpha_p.png")
    args = parser.parse_args()
    fig, ax = plt.subplots(figsize=(7.5, 4.2), constrained_layout=True)
    for velocity, colour in ((25, "tab:blue"), (50, "tab:green"), (75, "tab:red")):
        points = landscape(velocity)
        if not points:
            continue
        alpha_p, iterations = zip(*points, strict=True)
        ax.plot(alpha_p, iterations, "o-", color=colour, label=f"V = {velocity} m/s")
        best = min(points, key=lambda p: p[1])
        ax.plot(*best, "*", ms=14, color=colour)
    ax.axvline(BEST_CONSTANT_ALPHA_P, color="k", ls="--", lw=1, label="best single constant (0.875)")
    ax.set(xlabel="alpha_p (alpha_u = 0.95)", ylabel="SIMPLE iterations to the test criterion",
           title="full mesh, h: constant factors (star: each velocity's best)")
    ax.legend(fontsize=8)
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
