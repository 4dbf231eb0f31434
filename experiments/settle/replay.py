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

from foam_bridge import SettleRule, TableReader, quantity_name, row_scale, time_series
from foam_bridge._answer_monitor import SAMPLE_FUNCTION, SAMPLE_INTERVAL, VALUE_STRIDE, new_track
from foam_bridge._settle_verdict import judge, judge_due


def _value_rows(case: Path, start: int, budget: int) -> list[tuple[int, str, np.ndarray, float]]:
    """Every function-object row a settle run reads (every VALUE_STRIDE-th), up to the budget, in
    iteration order: (iteration, quantity, value, the row's scale floor)."""
    rows = []
    for key, path in time_series(case).items():
        if key.startswith(f"{SAMPLE_FUNCTION}/"):
            continue
        for time_value, row, columns in TableReader(path).read(VALUE_STRIDE) or []:
            at = int(round(time_value)) - start
            if at <= budget:
                floor = row_scale(list(columns.values()))
                rows += [(at, quantity_name(key, row, column), np.asarray(value, dtype=np.float64), floor)
                         for column, value in columns.items()]
    return sorted(rows, key=lambda row: row[0])


def replay(directory: Path, tolerance: float, verbose: bool = False, fields_only: bool = False,
           at_criterion: bool = False) -> dict:
    """``at_criterion``: a converging case as solve runs it, to its own criterion (its last sample before
    the iteration the criterion is met, judged there as the monitor judges a run that ended)."""
    record = json.loads((directory / "reference.json").read_text())
    samples = directory / "samples"
    its = np.load(samples / "iterations.npy")
    budget = record["budget"]
    if at_criterion and record["criterion_met_at"] is not None:
        budget = min(budget, record["criterion_met_at"])
    keep = (its <= budget) & (its % SAMPLE_INTERVAL == 0)  # what a settle run samples
    stacks = {name: np.load(samples / f"{name}.npy", mmap_mode="r") for name in record["fields"]}
    truth = {name: entry["errors"] for name, entry in record["fields"].items()}
    halves = {name: entry["half_range_last_third"] for name, entry in record["fields"].items()}
    tracks = {name: new_track(name, is_field=True) for name in record["fields"]}
    values = [] if fields_only else _value_rows(directory / "case", record["start"], budget)
    if not fields_only:
        truth.update({name: entry["errors"] for name, entry in record["values"].items()})
        halves.update({name: entry["half_range_last_third"] for name, entry in record["values"].items()})
    since, stop, outcome = None, None, None
    ratios, below = [], 0
    checks = 0
    last = None
    cursor = 0
    sampled = np.flatnonzero(keep)
    for index in sampled:
        n = int(its[index])
        for name in record["fields"]:
            tracks[name].add(n, np.asarray(stacks[name][index], dtype=np.float64))
        while cursor < len(values) and values[cursor][0] <= n:
            at, name, value, floor = values[cursor]
            if name not in tracks:
                tracks[name] = new_track(name, is_field=False)
            tracks[name].add(at, value, floor)
            cursor += 1
        if not judge_due(n, last) and not (at_criterion and index == sampled[-1]):
            continue
        last = n
        verdict, since = judge(tracks, n, SettleRule(tolerance), since)
        for name, found in verdict.estimates.items():
            true = truth[name][index] if name in truth and index < len(truth[name]) else None
            if np.isfinite(found.error) and true and true > 1e-7:
                ratios.append(found.error / true)
                below += found.error < true
                checks += 1
        if verbose and n % 100 == 0:
            print(n, {k: f"{v.model[:4]} {v.error:.1e}/{truth[k][index]:.1e}" for k, v in
                      verdict.estimates.items() if k in truth})
        if stop is None:  # the report: the verdict that stopped the run, else the last (the budget's)
            reported, reported_at = verdict, index
            if verdict.outcome is not None:
                stop, outcome = n, verdict.outcome
    if stop is None:
        reported_at = index  # the truth at the budget's sample, as before
    stop_truth = {name: truth[name][reported_at] for name in tracks
                  if name in truth and reported_at < len(truth[name])}
    stop_estimate = {name: e.error for name, e in reported.estimates.items() if name in truth}
    stop_models = {name: e.model for name, e in reported.estimates.items()}
    curves = [truth[name][:len(its[keep])] for name in tracks if name in truth]
    length = min(len(curve) for curve in curves)  # a value's curve may end sooner (fewer rows)
    worst = np.max(np.asarray([curve[:length] for curve in curves], dtype=np.float64), axis=0)
    within = np.flatnonzero(worst > tolerance)
    first = int(its[within[-1] + 1]) if len(within) and within[-1] + 1 < len(worst) else (
        int(its[0]) if not len(within) else None)
    result = {"case": record["case"], "kind": record["kind"], "budget": budget,
              "criterion_met_at": record["criterion_met_at"], "stop": stop, "outcome": outcome,
              "first_within": first, "median_ratio": float(np.median(ratios)) if ratios else None,
              "below_share": below / checks if checks else None}
    result.update(stop_truth=stop_truth, stop_estimate=stop_estimate, stop_models=stop_models,
                  reference_half_range={name: halves[name] for name in stop_truth})
    return result


def summary(results: list[dict], tolerance: float) -> dict:
    """Over the cases, as evaluate.py's table counts them: every (case, quantity) at the stop or the
    budget (the share where the estimate is at or above the truth, the median estimate / truth, the
    misses), the settled stops against 1.5 x the first iteration within the tolerance, the oscillating
    stops' half-ranges against the reference's, and the iterations against the budget."""
    pairs, misses, late, short, spent = [], [], [], [], []
    for found in results:
        stop = found["stop"] or found["budget"]
        spent.append(stop / found["budget"])
        for name, true in found["stop_truth"].items():
            guess = found["stop_estimate"].get(name)
            if guess is None or not np.isfinite(guess) or true is None:
                continue
            pairs.append((guess, true))
            if guess < true:
                misses.append(f"{found['case']} {name} {found['stop_models'].get(name)} "
                              f"{guess:.2g} < {true:.2g}")
        if found["outcome"] == "settled":
            first = found["first_within"]
            if first is None or stop > 1.5 * first or max(found["stop_truth"].values()) > tolerance:
                late.append(f"{found['case']} stop {stop} first {first}")
        elif found["outcome"] is not None:
            short += [f"{found['case']} {name} {found['stop_estimate'].get(name, 0):.2g} < {half:.2g}"
                      for name, half in found["reference_half_range"].items()
                      if found["stop_estimate"].get(name, 0) < half]
    ratios = [guess / true for guess, true in pairs if true > 0]
    return {"cases": len(results), "median_iterations_over_budget": float(np.median(spent)),
            "pairs": len(pairs), "share_held": float(np.mean([g >= t for g, t in pairs])) if pairs else None,
            "median_ratio": float(np.median(ratios)) if ratios else None, "misses": misses,
            "settled_late_or_off": late, "oscillating_half_range_short": short}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, nargs="+")
    parser.add_argument("--tolerance", type=float, default=1e-3)
    parser.add_argument("--verbose", action="store_true")
    parser.add_argument("--fields-only", action="store_true", help="the fields alone, no function objects")
    parser.add_argument("--at-criterion", action="store_true",
                        help="converging cases: to their own criterion, as solve runs them")
    args = parser.parse_args()
    results = []
    for directory in args.runs:
        results.append(replay(directory, args.tolerance, args.verbose, args.fields_only, args.at_criterion))
        print(json.dumps({k: results[-1][k] for k in ("case", "kind", "stop", "outcome", "first_within",
                                                      "median_ratio", "below_share")}))
    print(json.dumps(summary(results, args.tolerance), default=lambda v: float(f"{v:.3g}")))


if __name__ == "__main__":
    main()
