# SPDX-License-Identifier: GPL-3.0-or-later
"""What did a run on generated cases try, and how much did its reward tell it? From RUN/episodes.csv and
the generator manifests of its cases, per algorithm:

- how far the factors it played moved from each case's own (the spread, over episodes, of an episode's
  mean alpha_u, alpha_p and alpha_t minus the case's own), and where they sat on average;
- how noisy one case's cost is between episodes (median over cases met 4 times or more of the coefficient
  of variation of converged episodes' iterations and solver CPU seconds);
- the outcomes (converged, truncated at the budget, diverged);
- what the factors do to the price of an iteration: within each case, a least-squares fit of
  log(CPU seconds per iteration) on the episode's mean factors (deviations from the case's means), its
  change per +0.1 of each factor and the share of the variance it explains.

    python experiments/controller/generated-v1-setup/exploration.py RUN MANIFEST_DIR... [--last N]
"""

from __future__ import annotations

import argparse
import csv
import json
from collections import Counter, defaultdict
from pathlib import Path

import numpy as np

from foam_bridge import read_generated


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("manifests", type=Path, nargs="+")
    parser.add_argument("--last", type=int, default=0, help="only the episodes of the last N updates")
    args = parser.parse_args()
    specs = {case["name"]: case["spec"] for directory in args.manifests
             for case in read_generated(directory)["cases"]}
    rows = list(csv.DictReader((args.run / "episodes.csv").open()))
    if args.last:
        first = max(int(r["update"]) for r in rows) - args.last
        rows = [r for r in rows if int(r["update"]) > first]
    by_algorithm: dict[str, list[dict]] = defaultdict(list)
    for row in rows:
        by_algorithm[specs[row["case"]]["algorithm"]].append(row)
    for algorithm, found in sorted(by_algorithm.items()):
        offsets = np.array([_offset(row, dict(specs[row["case"]]["factors"])) for row in found])
        its_cv, cpu_cv = _noise(found)
        print(f"{algorithm}: {len(found)} episodes ({dict(Counter(r['outcome'] for r in found))}); factors "
              f"played minus own (U, p, turbulence): mean {np.round(offsets.mean(0), 3).tolist()}, spread "
              f"{np.round(offsets.std(0), 3).tolist()}; within a case, cost varies by {its_cv:.1%} in "
              f"iterations, {cpu_cv:.1%} in CPU seconds (median CV)")
        slope, explained = _price_fit(found)
        print(f"  log(CPU s per iteration) per +0.1 of (U, p, turbulence): {np.round(slope, 3).tolist()}, "
              f"R^2 {explained:.2f}")


def _mean_factors(row: dict) -> np.ndarray:
    """The factors an episode played, averaged over its steps (U, p, turbulence)."""
    return np.asarray(json.loads(row["actions"])).mean(0)


def _offset(row: dict, own: dict[str, float]) -> list[float]:
    return list(_mean_factors(row) - [own["U"], own["p"], own["turbulence"]])


def _converged_by_case(rows: list[dict], least: int) -> list[list[dict]]:
    """The converged episodes of each case met ``least`` times or more."""
    by_case: dict[str, list[dict]] = defaultdict(list)
    for row in rows:
        if row["outcome"] == "converged":
            by_case[row["case"]].append(row)
    return [found for found in by_case.values() if len(found) >= least]


def _price_fit(rows: list[dict]) -> tuple[np.ndarray, float]:
    centred = []
    for found in _converged_by_case(rows, 5):
        data = np.array([[np.log(float(r["solver_time_s"]) / int(r["iterations"])), *_mean_factors(r)]
                         for r in found])
        centred.append(data - data.mean(0))
    data = np.concatenate(centred)
    slope = np.linalg.lstsq(data[:, 1:], data[:, 0], rcond=None)[0]
    residual = data[:, 0] - data[:, 1:] @ slope
    return 0.1 * slope, float(1 - residual.var() / data[:, 0].var())


def _noise(rows: list[dict]) -> tuple[float, float]:
    its, cpu = [], []
    for found in _converged_by_case(rows, 4):
        for key, into in (("iterations", its), ("solver_time_s", cpu)):
            values = np.array([float(r[key]) for r in found])
            into.append(values.std() / values.mean())
    return float(np.median(its)), float(np.median(cpu))


if __name__ == "__main__":
    main()
