# SPDX-License-Identifier: GPL-3.0-or-later
"""How noisy is solver CPU as a reward? From a run's episodes.csv: within each case met at least 5 times,
the coefficient of variation of CPU seconds per SIMPLE iteration over its episodes, and the correlation of
that with the linear solvers' iterations per SIMPLE iteration (medians over the cases).

    python experiments/controller/generated-v1-setup/cpu_noise.py experiments/controller/generated-v1a-s0
"""

from __future__ import annotations

import csv
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np


def main(run: Path) -> None:
    by_case: dict[str, list[dict[str, str]]] = defaultdict(list)
    for row in csv.DictReader((run / "episodes.csv").open()):
        if row["outcome"] in ("converged", "truncated"):
            by_case[row["case"]].append(row)
    spread, correlation = [], []
    for rows in (rows for rows in by_case.values() if len(rows) >= 5):
        per_iteration = np.array([float(r["solver_time_s"]) / int(r["iterations"]) for r in rows])
        linear = np.array([float(r["linear_iterations"]) / int(r["iterations"]) for r in rows])
        spread.append(per_iteration.std() / per_iteration.mean())
        if linear.std() > 0:
            correlation.append(np.corrcoef(per_iteration, linear)[0, 1])
    print(f"{len(spread)} cases met 5 times or more: CPU per iteration varies by {np.median(spread):.1%} "
          f"(median CV); its correlation with linear iterations per iteration: median "
          f"{np.median(correlation):.2f} (quartiles {np.percentile(correlation, 25):.2f}, "
          f"{np.percentile(correlation, 75):.2f})")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
