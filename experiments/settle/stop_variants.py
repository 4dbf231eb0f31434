# SPDX-License-Identifier: GPL-3.0-or-later
"""What the oscillating stop's steadiness test costs and buys (issue 56, development only: spent sets).

    .venv/bin/python experiments/settle/stop_variants.py runs/settle-fresh-dev/ref runs/settle-fresh2/ref \
        --json experiments/settle/eval/stop-variants.json

Every reference run under the given directories whose case never meets its own criterion is replayed
(replay.py: fields and function objects, at a settle run's samples and checks) under the oscillating
stop's steadiness test as shipped (the latest window's mean and half-range within STABLE = 0.25 of the
half-range of the window before) and looser ones; at STABLE = 1 the half-range test is void (|a - b| <=
max(a, b) always): a run stops once its mean stays within its swing, even while the swing still shrinks.
Then, at the shipped STABLE, shorter windows (each a quarter, a fifth, a sixth of the run instead of a
third): a cycle that sets in at iteration s can stop a run no sooner than about 3s with windows of a third.
Per variant: the median iterations over the budget, how many cases stop by 0.40x, the share of (case,
quantity) pairs whose estimate is at or above the truth, the median estimate / true error (all pairs, and
those whose truth is resolved, >= 1e-5), and the cases whose reported half-range is short of the
reference's on some quantity.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

import replay
from evaluate import resolved_sharpness

import foam_bridge._settle_verdict as verdict
from foam_bridge import DEFAULT_TOLERANCE

#: (STABLE, CYCLE_FRACTION, MIN_CYCLE_WINDOW): the shipped test, looser ones, then shorter windows.
VARIANTS = ((0.25, 1 / 3, 300), (0.5, 1 / 3, 300), (0.75, 1 / 3, 300), (1.0, 1 / 3, 300),
            (0.25, 1 / 4, 300), (0.25, 1 / 5, 250), (0.25, 1 / 6, 200))


def measure(directories: list[Path], stable: float, fraction: float, least: int) -> dict:
    shipped = verdict.STABLE, verdict.CYCLE_FRACTION, verdict.MIN_CYCLE_WINDOW
    verdict.STABLE, verdict.CYCLE_FRACTION, verdict.MIN_CYCLE_WINDOW = stable, fraction, least
    try:
        results = [replay.replay(directory, DEFAULT_TOLERANCE) for directory in directories]
    finally:
        verdict.STABLE, verdict.CYCLE_FRACTION, verdict.MIN_CYCLE_WINDOW = shipped
    found = replay.summary(results, DEFAULT_TOLERANCE)
    pairs = [(r["stop_estimate"].get(name), true) for r in results for name, true in r["stop_truth"].items()]
    sharp = resolved_sharpness([(e, t) for e, t in pairs if e is not None and t is not None])
    spent = [(r["stop"] or r["budget"]) / r["budget"] for r in results]
    return {"stable": stable, "window_fraction": fraction, "min_window": least, "cases": len(results),
            "median_iterations_over_budget": statistics.median(spent),
            "stopped_by_0.40": sum(x <= 0.40 for x in spent), "pairs": found["pairs"],
            "share_held": found["share_held"], "median_estimate_over_true": found["median_ratio"],
            "median_estimate_over_true_resolved": sharp["median_estimate_over_true_resolved"],
            "half_range_short": sorted({item.split()[0] for item in found["oscillating_half_range_short"]}),
            "stops": {r["case"]: [r["stop"], r["outcome"]] for r in results}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("roots", type=Path, nargs="+", help="directories of reference runs")
    parser.add_argument("--json", type=Path, required=True)
    args = parser.parse_args()
    directories = [d for root in args.roots for d in sorted(root.iterdir())
                   if (d / "reference.json").is_file()
                   and json.loads((d / "reference.json").read_text())["criterion_met_at"] is None]
    rows = []
    for stable, fraction, least in VARIANTS:
        rows.append(measure(directories, stable, fraction, least))
        row = rows[-1]
        print(f"STABLE {stable}, windows 1/{round(1 / fraction)} (>= {least}): "
              f"median {row['median_iterations_over_budget']:.2f} x budget, "
              f"{row['stopped_by_0.40']}/{row['cases']} by 0.40x, held {row['share_held']:.3f}, "
              f"ratio {row['median_estimate_over_true']:.2f} "
              f"({row['median_estimate_over_true_resolved']:.2f} resolved), "
              f"half-range short on {len(row['half_range_short'])}", flush=True)
    args.json.parent.mkdir(parents=True, exist_ok=True)
    record = {"cases": [d.name for d in directories], "variants": rows}
    args.json.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
