"""SIMPLE iterations against a constant alpha_p (alpha_u 0.95), one line per inlet velocity (grid-foam CSVs).

    python experiments/foam/plot_landscape.py --out experiments/foam/constant_factors/fine_alpha_p.png

Reads the landscape CSVs of ``learnability.py`` (full mesh, test criterion, checked at alpha_u 0.9), plots
the test velocities 25, 50 and 75 m/s, and marks the single best constant's alpha_p (h 0.875, 2h 0.3) and
each velocity's own best.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from learnability import GEOMETRIES, HERE, TEST_VELOCITIES, landscape  # noqa: E402  (this folder)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=HERE / "fine_alpha_p.png")
    args = parser.parse_args()
    fig, axes = plt.subplots(1, len(GEOMETRIES), figsize=(13, 4.2), constrained_layout=True)
    for ax, (geometry, globs, best_alpha_p) in zip(axes, GEOMETRIES, strict=True):
        table = landscape(globs)
        for velocity, colour in zip(TEST_VELOCITIES, ("tab:blue", "tab:green", "tab:red"), strict=True):
            points = sorted(table.get(velocity, {}).items())
            if not points:
                continue
            alpha_p, iterations = zip(*points, strict=True)
            ax.plot(alpha_p, iterations, "o-", color=colour, label=f"V = {velocity:g} m/s")
            ax.plot(*min(points, key=lambda p: p[1]), "*", ms=14, color=colour)
        ax.axvline(best_alpha_p, color="k", ls="--", lw=1, label=f"best single constant ({best_alpha_p:g})")
        ax.set(xlabel="alpha_p (alpha_u = 0.95)", ylabel="SIMPLE iterations to the test criterion",
               title=f"full mesh, {geometry}: constant factors (star: each velocity's best)")
        ax.legend(fontsize=8)
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
