"""Per case of a train-foam --family run: its episodes' iterations relative to the case's own settings, by
window of updates, and its failures; the median over the cases at the end.

    .venv/bin/python experiments/controller/family-v1-setup/progress.py \
        experiments/controller/family-v1 [--window 5]

A case's own iterations are 100 / its reward_scale (jaxsimrl.apps.foam.cli.train_family.REWARD_UNIT). An
episode that failed or reached its budget counts at its budget (a case's reward does the same).
"""

from __future__ import annotations

import argparse
import csv
import json
import statistics
from collections import defaultdict
from pathlib import Path

REWARD_UNIT = 100.0


def ratios(run: Path, window: int) -> dict[str, dict[int, list[float]]]:
    """{case: {first update of the window: [iterations / own, ...]}}."""
    family = json.loads((run / "config.json").read_text())["family"]
    table: dict[str, dict[int, list[float]]] = defaultdict(lambda: defaultdict(list))
    with (run / "episodes.csv").open() as handle:
        for row in csv.DictReader(handle):
            case = family[row["case"]]
            own = REWARD_UNIT / case["reward_scale"]
            counted = int(row["iterations"]) if row["outcome"] == "converged" else case["max_iterations"]
            start = (int(row["update"]) - 1) // window * window + 1
            table[row["case"]][start].append(counted / own)
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", type=Path)
    parser.add_argument("--window", type=int, default=5, help="updates per column")
    args = parser.parse_args()
    table = ratios(args.run, args.window)
    starts = sorted({start for by in table.values() for start in by})
    print(f"{'case':24s}" + "".join(f"{f'u{s}-':>9s}" for s in starts))
    for name in sorted(table):
        cells = [statistics.median(table[name][s]) if table[name].get(s) else float("nan") for s in starts]
        print(f"{name:24s}" + "".join(f"{c:9.2f}" for c in cells))
    last = [statistics.median(by[starts[-1]]) for by in table.values() if by.get(starts[-1])]
    if last:
        print(f"median over cases, last window: {statistics.median(last):.2f}x own")


if __name__ == "__main__":
    main()
