"""SIMPLE iterations against a constant alpha_p (alpha_u 0.95), one line per inlet velocity (grid-foam CSVs).

    python experiments/foam/plot_landscape.py --out experiments/foam/constant_factors/fine_alpha_p.png

Reads ``constant_factors/fine_alpha_p_V{25,50,75}*/grid.csv`` (h) and ``fine_2h_alpha_p_V*`` (2h) (full
mesh, test criterion, checked at alpha_u 0.9) and marks the single best constant's alpha_p (h 0.875, 2h 0.3)
and each velocity's own best.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = Path(__file__).parent / "constant_factors"
#: (panel title, CSV directory prefix, the best single constant's alpha_p) per geometry
GEOMETRIES = (("h", "fine_alpha_p_V", 0.875), ("2h", "fine_2h_alpha_p_V", 0.3))


def landscape(prefix: str, velocity: int) -> list[tuple[float, int]]:
    """(alpha_p, iterations) of every converged cell at ``velocity``, sorted by alpha_p."""
    points = {}
    for path in sorted(HERE.glob(f"{prefix}{velocity}*/grid.csv")):
        with open(path, newline="") as handle:
            for row in csv.DictReader(handle):
                if row["outcome"] == "converged" and float(row["alpha_u"]) == 0.95:
                    points[float(row["alpha_p"])] = int(row["iterations"])
    return sorted(points.items())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "fine_alpha_p.png")
    args = parser.parse_args()
    fig, axes = plt.subplots(1, len(GEOMETRIES), figsize=(13, 4.2), constrained_layout=True)
    for ax, (geometry, prefix, best_alpha_p) in zip(axes, GEOMETRIES, strict=True):
        for velocity, colour in ((25, "tab:blue"), (50, "tab:green"), (75, "tab:red")):
            points = landscape(prefix, velocity)
            if not points:
                continue
            alpha_p, iterations = zip(*points, strict=True)
            ax.plot(alpha_p, iterations, "o-", color=colour, label=f"V = {velocity} m/s")
            ax.plot(*min(points, key=lambda p: p[1]), "*", ms=14, color=colour)
        ax.axvline(best_alpha_p, color="k", ls="--", lw=1, label=f"best single constant ({best_alpha_p:g})")
        ax.set(xlabel="alpha_p (alpha_u = 0.95)", ylabel="SIMPLE iterations to the test criterion",
               title=f"full mesh, {geometry}: constant factors (star: each velocity's best)")
        ax.legend(fontsize=8)
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
