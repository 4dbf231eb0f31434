# SPDX-License-Identifier: GPL-3.0-or-later
"""Replay a reference run's field samples through the answer monitor's estimator and verdict (issue 56,
development only: never on the fresh set).

    .venv/bin/python experiments/settle/replay.py runs/settle-dev/ref/NAME [...] [--tolerance 1e-3]

For each reference run (experiments/settle/reference.py's ``--out``): the samples a settle run takes (every
SAMPLE_INTERVAL iterations) up to the budget, fed one by one to foam_bridge's estimator and verdict, at the
monitor's cadence (fields only: the function objects' rows are in the reference JSON, not replayed here).
Prints, per case: where the
verdict would stop and why, the true error there (from the reference), the first iteration from which the
answer stays within the tolerance, and over every check the estimate / truth ratios (median, and the share
of checks where the estimate is below the truth).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from foam_bridge import QuantityTrack, SettleRule
from foam_bridge._answer_monitor import FIELD_SNAPSHOTS, SAMPLE_INTERVAL
from foam_bridge._settle_verdict import judge, judge_due


def replay(directory: Path, tolerance: float, verbose: bool = False) -> dict:
    record = json.loads((directory / "reference.json").read_text())
    samples = directory / "samples"
    its = np.load(samples / "iterations.npy")
    budget = record["budget"]
    keep = (its <= budget) & (its % SAMPLE_INTERVAL == 0)  # what a settle run samples
    stacks = {name: np.load(samples / f"{name}.npy", mmap_mode="r") for name in record["fields"]}
    truth = {name: record["fields"][name]["errors"] for name in record["fields"]}
    tracks = {name: QuantityTrack(name, max_snapshots=FIELD_SNAPSHOTS) for name in record["fields"]}
    since, stop, outcome = None, None, None
    ratios, below = [], 0
    checks = 0
    last = None
    for index in np.flatnonzero(keep):
        n = int(its[index])
        for name, track in tracks.items():
            track.add(n, np.asarray(stacks[name][index], dtype=np.float64))
        if not judge_due(n, last):
            continue
        last = n
        verdict, since = judge(tracks, n, SettleRule(tolerance), since)
        for name, found in verdict.estimates.items():
            true = truth[name][index]
            if np.isfinite(found.error) and true and true > 1e-7:
                ratios.append(found.error / true)
                below += found.error < true
                checks += 1
        if verbose and n % 100 == 0:
            print(n, {k: f"{v.model[:4]} {v.error:.1e}/{truth[k][index]:.1e}" for k, v in
                      verdict.estimates.items()})
        if verdict.outcome is not None and stop is None:
            stop, outcome = n, verdict.outcome
            stop_truth = {name: truth[name][index] for name in tracks}
            stop_estimate = {name: e.error for name, e in verdict.estimates.items()}
            stop_models = {name: e.model for name, e in verdict.estimates.items()}
    worst = np.max(np.asarray([truth[name] for name in tracks]), axis=0)
    within = np.flatnonzero(worst > tolerance)
    first = int(its[within[-1] + 1]) if len(within) and within[-1] + 1 < len(worst) else (
        int(its[0]) if not len(within) else None)
    result = {"case": record["case"], "kind": record["kind"], "budget": budget,
              "criterion_met_at": record["criterion_met_at"], "stop": stop, "outcome": outcome,
              "first_within": first, "median_ratio": float(np.median(ratios)) if ratios else None,
              "below_share": below / checks if checks else None}
    if stop is not None:
        result.update(stop_truth=stop_truth, stop_estimate=stop_estimate, stop_models=stop_models,
                      reference_half_range={name: record["fields"][name]["half_range_last_third"]
                                            for name in tracks})
    return result


def summary(results: list[dict], tolerance: float) -> dict:
    """Over the cases: the estimate / truth ratio of every (case, quantity) at the stop (median, share
    below 1), the settled stops against 1.5 x the first iteration within the tolerance, the oscillating
    stops' half-ranges against the reference's, and the iterations against the budget."""
    ratios, late, short, spent = [], [], [], []
    for found in results:
        stop = found["stop"] or found["budget"]
        spent.append(stop / found["budget"])
        if found["stop"] is None:
            continue
        for name, true in found["stop_truth"].items():
            ratios.append(found["stop_estimate"][name] / max(true, 1e-12))
        if found["outcome"] == "settled":
            first = found["first_within"]
            if first is None or stop > 1.5 * first or max(found["stop_truth"].values()) > tolerance:
                late.append(found["case"])
        else:
            short += [f"{found['case']} {name}" for name, half in found["reference_half_range"].items()
                      if found["stop_estimate"][name] < half]
    ratios = np.asarray(ratios)
    return {"cases": len(results), "median_iterations_over_budget": float(np.median(spent)),
            "pairs": len(ratios), "median_ratio": float(np.median(ratios)) if len(ratios) else None,
            "share_below": float(np.mean(ratios < 1)) if len(ratios) else None,
            "settled_late_or_off": late, "oscillating_half_range_short": short}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, nargs="+")
    parser.add_argument("--tolerance", type=float, default=1e-3)
    parser.add_argument("--verbose", action="store_true")
    args = parser.parse_args()
    results = []
    for directory in args.runs:
        results.append(replay(directory, args.tolerance, args.verbose))
        print(json.dumps(results[-1], default=lambda v: float(f"{v:.3g}")))
    print(json.dumps(summary(results, args.tolerance), default=lambda v: float(f"{v:.3g}")))


if __name__ == "__main__":
    main()
