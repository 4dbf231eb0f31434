# SPDX-License-Identifier: GPL-3.0-or-later
"""Issue 46's evaluation of ``jaxsimrl solve``'s default on one set of cases, as a user runs it.

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/solve-safety/evaluate.py \
        runs/heldout-v2 --set experiments/controller/heldout-v2/heldout.json --out DIR \
        --beside bandit constant guarded lean
    .venv/bin/python experiments/solve-safety/evaluate.py runs/tutorials --tutorials --out DIR

Per case (its own mesh, criterion and budget), every run through ``jaxsimrl solve`` or as
``--compare-constant`` runs a constant:

- ``default``: ``solve --compare`` with no controller named (the default), its own run and the spread run
  beside it (three solvers on the machine's cores: the agreement figures come from here, and the solver
  CPU seconds of cases whose own run takes WALL_MIN_S or more);
- ``cpu``: for cases whose own run takes less, the default alone and the own run alone, alternated, 3 times
  each: solver CPU as the median of the 3 pairs' ratios (``--no-pairs``: not run);
- ``--beside``: what a user has besides the default, each run once: ``bandit``, ``guarded`` and
  ``residual-rule`` (``solve --controller NAME``), ``lean`` (``solve --solves lean``) and ``constant``
  (the training family's constant for the case's algorithm, jaxsimrl.apps.foam.solve.settings.
  FAMILY_CONSTANT, a plain run).

Also the default's detector (its switch back to the case's own factors, solve.json's ``fallback``): the
iteration it fired, why, the first step boundary at which the controlled run was behind the own run
(distance to the criterion more than BEHIND_DECADES above the own run's at the same iteration), the
latency from there, and whether it fired where the run was never behind (a false fire).

One JSON line per case in DIR/rows.jsonl, appended as each finishes; a rerun skips the cases it holds.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path
from typing import Any

from foam_bridge import criterion_distance
from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.apps.foam.solve.own import run_own
from jaxsimrl.apps.foam.solve.settings import FAMILY_CONSTANT, read_case_settings

WALL_MIN_S = 20.0
PAIRS = 3
TIMEOUT_S = 3600.0
BEHIND_DECADES = 0.1
#: The solve benchmark's five tutorials (benchmarks/bench_solve.py).
TUTORIALS = ("pitzDaily", "T3A", "backwardFacingStep2D", "pitzDailyExptInlet", "airFoil2D")


def distances(residuals: dict[str, list[float | None]], criterion: dict[str, float]) -> list[float]:
    """The distance to the criterion at every iteration of one run's residual history (solve.json)."""
    count = min((len(values) for values in residuals.values()), default=0)
    rows = ({name: values[k] for name, values in residuals.items() if values[k] is not None}
            for k in range(count))
    return [criterion_distance(row, criterion) for row in rows]


def detector(data: dict[str, Any], own_residuals: dict[str, list[float | None]]) -> dict[str, Any]:
    """When a run's detector fired (its rule's own "detector: ..." switch back to the case's own factors, or
    the watchdog), why, when the run first fell behind the own run (``own_residuals``: its history), the
    latency from there, and whether it fired where the run was never behind (a false fire)."""
    criterion = data["settings"]["criterion"]
    ours, own = distances(data["residuals"]["controlled"], criterion), distances(own_residuals, criterion)
    boundaries = [step["to_iteration"] for step in data["steps"] if "to_iteration" in step]
    behind = next((k for k in boundaries if 0 < k <= min(len(ours), len(own))
                   and ours[k - 1] > own[k - 1] + BEHIND_DECADES), None)
    fired = next((event for event in data["fallback"] if event["kind"] == "watchdog"
                  or event["reason"].startswith("detector")), None)
    at = None if fired is None else fired["at_iteration"]
    return {"fired_at": at, "why": None if fired is None else fired["reason"], "behind_from": behind,
            "latency": None if at is None or behind is None or behind > at else at - behind,
            "false_fire": fired is not None and (behind is None or behind > at),
            "events": [[event["kind"], event["at_iteration"], event["reason"]] for event in data["fallback"]]}


def default_row(case: Path, scratch: Path) -> dict[str, Any]:
    data = solve_case(case, scratch / "default", compare=True, step_timeout_s=900).data
    result, own = data["result"], data["compare"]["own"]
    agreement, spread = own.get("agreement", {}), own.get("spread", {})
    return {"controller": data["controller"].get("rule") or "learned",
            "converged": result["converged"], "iterations": result["iterations"],
            "cpu_s": round(result["solver_cpu_time_s"], 2), "fields_from": result["fields_from"],
            "own": {"converged": own["converged"], "iterations": own["iterations"],
                    "cpu_s": round(own["solver_cpu_time_s"], 2)},
            "agree": agreement.get("agree"), "agreement_reason": agreement.get("reason"),
            "differences": {kind: {name: entry["value"] for name, entry in agreement.get(kind, {}).items()}
                            for kind in ("fields", "function_objects")},
            "tolerance": agreement.get("tolerance"),
            "spread": {key: spread.get(key) for key in ("measured", "nudge", "settled", "fields",
                                                        "function_objects", "iterations", "reason")},
            "detector": detector(data, data["residuals"].get("own", {})),
            "own_residuals": data["residuals"].get("own", {})}


def cpu_pairs(case: Path, scratch: Path) -> list[dict[str, float]]:
    """The default alone and the own run alone, alternated, PAIRS times: solver CPU seconds of each."""
    pairs = []
    for k in range(PAIRS):
        ours = solve_case(case, scratch / f"cpu-default-{k}", step_timeout_s=900).data["result"]
        own = run_own(case, scratch / f"cpu-own-{k}", "own", TIMEOUT_S)
        pairs.append({"default_s": round(ours["solver_cpu_time_s"], 2), "own_s": round(own.cpu_time_s, 2),
                      "ratio": round(ours["solver_cpu_time_s"] / own.cpu_time_s, 3)})
    return pairs


def _solved(data: dict[str, Any]) -> dict[str, Any]:
    result = data["result"]
    return {"converged": result["converged"], "iterations": result["iterations"],
            "cpu_s": round(result["solver_cpu_time_s"], 2), "fields_from": result["fields_from"]}


def beside(case: Path, scratch: Path, which: list[str], own_residuals: dict[str, Any]) -> dict[str, Any]:
    """What a user has beside the default, each run once: the ``bandit``, ``guarded`` and ``residual-rule``
    through solve, ``lean`` (solve's own factors with --solves lean), and ``constant`` (the training
    family's constant for the case's algorithm, a plain run)."""
    rows: dict[str, Any] = {}
    for name in which:
        if name == "constant":
            factors = list(FAMILY_CONSTANT[read_case_settings(case).variant])
            plain = run_own(case, scratch / name, name, TIMEOUT_S, factors=factors)
            rows[name] = {"factors": factors, "converged": plain.converged, "iterations": plain.iterations,
                          "cpu_s": round(plain.cpu_time_s, 2)}
        elif name == "lean":
            rows[name] = _solved(solve_case(case, scratch / name, solves="lean", step_timeout_s=900).data)
        else:
            data = solve_case(case, scratch / name, rule=name, step_timeout_s=900).data
            rows[name] = {**_solved(data), "detector": detector(data, own_residuals)}
    return rows


def evaluate(case: Path, which: list[str], pairs: bool) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix=f"safety-{case.name}-") as scratch:
        row = {"case": case.name, "algorithm": read_case_settings(case).variant,
               **default_row(case, Path(scratch))}
        if pairs and row["own"]["cpu_s"] < WALL_MIN_S:
            row["cpu_pairs"] = cpu_pairs(case, Path(scratch))
            row["cpu_ratio"] = statistics.median(pair["ratio"] for pair in row["cpu_pairs"])
        elif row["own"]["cpu_s"]:
            row["cpu_ratio"] = round(row["cpu_s"] / row["own"]["cpu_s"], 3)
        row.update(beside(case, Path(scratch), which, row.pop("own_residuals")))
    row["iteration_ratio"] = round(row["iterations"] / row["own"]["iterations"], 3)
    return row


def add_case_set(parser: argparse.ArgumentParser) -> None:
    """The arguments that name the cases: their directory, and a heldout.json or the tutorials."""
    parser.add_argument("root", type=Path, help="the directory holding the cases")
    parser.add_argument("--set", type=Path, help="a heldout.json: its evaluation cases")
    parser.add_argument("--tutorials", action="store_true", help="the solve benchmark's five tutorials")


def case_names(args: argparse.Namespace) -> list[str]:
    """The cases add_case_set's arguments name, in order."""
    if args.tutorials:
        return list(TUTORIALS)
    return [c["name"] for c in json.loads(args.set.read_text())["cases"] if c["in_evaluation"]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_case_set(parser)
    parser.add_argument("--cases", dest="only", nargs="+", help="these cases only")
    parser.add_argument("--beside", nargs="*", default=[],
                        choices=("bandit", "constant", "guarded", "lean", "residual-rule"),
                        help="also run these, once each")
    parser.add_argument("--no-pairs", action="store_false", dest="pairs",
                        help="no alternated CPU pairs (the CPU ratio from the --compare run)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    names = args.only or case_names(args)
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "rows.jsonl"
    held = {json.loads(line)["case"] for line in path.read_text().splitlines()} if path.exists() else set()
    for name in names:
        if name in held:
            continue
        row = evaluate(args.root / name, args.beside, args.pairs)
        with path.open("a") as stream:
            stream.write(json.dumps(row) + "\n")
        print(f"{name}: default {row['iterations']} / own {row['own']['iterations']} "
              f"(cpu ratio {row['cpu_ratio']}), agree {row['agree']}, detector {row['detector']}", flush=True)


if __name__ == "__main__":
    main()
