# SPDX-License-Identifier: GPL-3.0-or-later
"""Issue 56's evaluation: `jaxsimrl solve` with its default stop on the answer, case by case, each result
held against the case's reference run (experiments/settle/reference.py).

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/settle/evaluate.py run CASES_DIR \
        --out runs/settle-eval/SET --rows experiments/settle/eval/SET/rows.jsonl [--only NAME ...]
    .venv/bin/python experiments/settle/evaluate.py table --rows experiments/settle/eval/SET/rows.jsonl \
        --references experiments/settle/references/SET --arrays runs/settle-SET/ref --table .../table.md

``run``: every case of CASES_DIR solved once, as a user would (``solve_case`` with its defaults: the case's
own settings, ``--settle`` 1e-3), one at a time; a row per case appended to ``--rows`` (a case with a row is
not run again). ``table``: each row joined with its case's reference: the true error of every field (the
fields written at the stop against the reference answer, reference.npz under ``--arrays``) and of every
function-object value (its last row against the reference's value), the first iteration from which every
quantity stays within the tolerance of the reference, the oscillating stops' half-ranges against the
reference's; one table row per case, every case, and the targets' figures.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import time
from pathlib import Path

import numpy as np

from foam_bridge import (
    TableReader,
    quantity_name,
    read_internal_field,
    relative_difference,
    relative_l2,
    time_series,
)

TOLERANCE = 1e-3
#: The estimate's sharpness (the median of estimate / true error) is also given over the pairs whose true
#: error is at least this: a function object writes 6 significant digits, so a smaller true error is not
#: resolved (2-D side forces and rolling moments of 1e-20 would give ratios of 1e15). Fixed after
#: fresh-set-2's evaluation (which reports both) and before fresh-set-3's.
RESOLVED = 1e-5


def run(cases: Path, out: Path, rows: Path, only: list[str] | None) -> None:
    from jaxsimrl.apps.foam.solve import solve_case

    done = {json.loads(line)["case"] for line in rows.read_text().splitlines()} if rows.exists() else set()
    rows.parent.mkdir(parents=True, exist_ok=True)
    for case in sorted(path for path in cases.iterdir() if path.is_dir()):
        if case.name in done or (only and case.name not in only):
            continue
        target = out / case.name
        started = time.monotonic()
        try:
            report = solve_case(case, target)
            result, answer = report.data["result"], report.data.get("answer") or {}
            row = {"case": case.name, "outcome": result["outcome"], "iterations": result["iterations"],
                   "converged": result["converged"], "solver_cpu_s": result["solver_cpu_time_s"],
                   "wall_s": time.monotonic() - started, "budget": report.data["settings"]["max_iterations"],
                   "iterative_error": result.get("iterative_error", {}),
                   "quantities": answer.get("quantities", {}), "decided_at": answer.get("decided_at"),
                   "monitor_cpu_s": answer.get("monitor_cpu_s"), "notes": answer.get("notes", []),
                   "time_directory": result["time_directory"], "out": str(target)}
        except Exception as err:  # noqa: BLE001 - a failed case is a row, not the end of the evaluation
            row = {"case": case.name, "outcome": "failed", "error": f"{type(err).__name__}: {err}"}
        with open(rows, "a") as file:
            file.write(json.dumps(row) + "\n")
        print(f"{case.name}: {row['outcome']} after {row.get('iterations')} iterations", flush=True)


def true_errors(row: dict, reference: dict, arrays: Path) -> dict[str, float]:
    """{quantity: relative error of the answer the solve left, from the reference answer}."""
    out = Path(row["out"])
    stop = out / row["time_directory"]
    found = {}
    answer = np.load(arrays / reference["case"] / "reference.npz")
    for name in reference["fields"]:
        field = read_internal_field(stop / name)
        if field is not None:
            found[name] = relative_l2(field[0], answer[name])
    last = {}
    for key, path in time_series(out).items():
        rows = TableReader(path).read() or []
        for _, row_key, columns in rows:
            for column, value in columns.items():
                last[quantity_name(key, row_key, column)] = value
    for name, ref in reference["values"].items():
        if name in last:
            found[name] = relative_difference(last[name], ref["reference"], ref["floor"])
    return found


def first_within(reference: dict, tolerance: float) -> int | None:
    """The first sampled iteration from which every field and value stays within ``tolerance`` of the
    reference up to the budget (None: never)."""
    curves = [f["errors"] for f in reference["fields"].values()]
    curves += [v["errors"] for v in reference["values"].values()]
    length = min(len(c) for c in curves)
    worst = np.max(np.asarray([c[:length] for c in curves], dtype=np.float64), axis=0)
    above = np.flatnonzero(~(worst <= tolerance))
    iterations = reference["iterations"][:length]
    if not len(above):
        return iterations[0]
    return iterations[above[-1] + 1] if above[-1] + 1 < length else None


def judge_row(row: dict, reference: dict, arrays: Path) -> dict:
    truth = true_errors(row, reference, arrays)
    estimate = {k: v for k, v in row["iterative_error"].items() if v is not None}
    pairs = [(estimate[name], truth[name]) for name in truth if name in estimate]
    first = first_within(reference, TOLERANCE)
    halves = {name: (row["quantities"].get(name, {}).get("half_range"), entry["half_range_last_third"])
              for name, entry in {**reference["fields"], **reference["values"]}.items()}
    return {"case": row["case"], "outcome": row["outcome"], "iterations": row["iterations"],
            "budget": row["budget"], "reference_kind": reference["kind"], "first_within": first,
            "stop_over_first": row["iterations"] / first if first else None,
            "true_max": max(truth.values(), default=None),
            "estimate_max": max(estimate.values(), default=None),
            "pairs": pairs, "held": sum(e >= t for e, t in pairs), "solver_cpu_s": row["solver_cpu_s"],
            "monitor_cpu_s": row.get("monitor_cpu_s"),
            "half_short": [name for name, (ours, ref) in halves.items() if ours is not None and ours < ref],
            "cpu_to_budget_s": reference["cpu_to_budget_s"],
            "met_within_budget": reference["met_within_budget"]}


#: The fresh set's rule (experiments/settle/fresh-set/README.md), fixed before any run: a candidate whose
#: solver CPU to its budget is this or more is out.
CPU_LIMIT_S = 150.0


def why_out(reference: dict) -> str:
    """Why a candidate is not in the set by the rule ("" when it is in)."""
    if reference["met_within_budget"]:
        return f"its own criterion met at iteration {reference['criterion_met_at']}"
    if reference["exit_code"] != 0 or reference["iterations_run"] < reference["end"] - reference["start"]:
        return f"its reference run crashed at iteration {reference['iterations_run']}"
    if reference["cpu_to_budget_s"] is None or reference["cpu_to_budget_s"] >= CPU_LIMIT_S:
        return f"solver CPU to its budget {reference['cpu_to_budget_s']} s"
    return ""


def table(rows_path: Path, references: Path, arrays: Path, out: Path) -> None:
    rows = [json.loads(line) for line in rows_path.read_text().splitlines()]
    judged, left_out = [], []
    for row in rows:
        ref_path = references / f"{row['case']}.json"
        if not ref_path.is_file():
            left_out.append((row["case"], "no reference yet"))
            continue
        reference = json.loads(ref_path.read_text())
        reason = why_out(reference) or ("its solve failed" if row["outcome"] == "failed" else "")
        if reason:
            left_out.append((row["case"], reason))
            continue
        judged.append({**judge_row(row, reference, arrays),
                       "algorithm": "SIMPLEC" if reference["consistent"] else "SIMPLE"})
    solved = {row["case"] for row in rows}
    for ref_path in sorted(references.glob("*.json")):  # every candidate, run or not
        if ref_path.stem not in solved:
            left_out.append((ref_path.stem, why_out(json.loads(ref_path.read_text())) or "not solved"))
    lines = ["| case | algorithm | outcome | iterations / budget | first within 1e-3 | stop / first | "
             "true error (max) | estimate (max) | estimate >= true | half-range short | solver CPU s | "
             "monitor CPU s |", "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for j in judged:
        lines.append(f"| {j['case']} | {j['algorithm']} | {j['outcome']} | "
                     f"{j['iterations']} / {j['budget']} | "
                     f"{j['first_within']} | {_f(j['stop_over_first'], '.2f')} | {_f(j['true_max'])} | "
                     f"{_f(j['estimate_max'])} | "
                     f"{j['held']}/{len(j['pairs'])} | {len(j['half_short'])} | {j['solver_cpu_s']:.1f} | "
                     f"{_f(j['monitor_cpu_s'], '.2f')} |")
    pairs = [p for j in judged for p in j["pairs"]]
    ratios = [e / t for e, t in pairs if t > 0]
    settled = [j for j in judged if j["outcome"] == "settled"]
    summary = {"cases": len(judged), "out": dict(left_out),
               "simple": sum(j["algorithm"] == "SIMPLE" for j in judged),
               "simplec": sum(j["algorithm"] == "SIMPLEC" for j in judged),
               "cpu_30s_or_more": sum((j["cpu_to_budget_s"] or 0) >= 30 for j in judged),
               "median_iterations_over_budget": statistics.median(j["iterations"] / j["budget"]
                                                                  for j in judged),
               "pairs": len(pairs),
               "share_held": sum(e >= t for e, t in pairs) / len(pairs) if pairs else None,
               "median_estimate_over_true": statistics.median(ratios) if ratios else None,
               **resolved_sharpness(pairs),
               "settled": [j["case"] for j in settled],
               "settled_within_1_5x_first": [j["case"] for j in settled
                                             if (j["stop_over_first"] or math.inf) <= 1.5],
               "settled_true_within_tolerance": [j["case"] for j in settled
                                                 if j["true_max"] is not None and j["true_max"] <= TOLERANCE],
               "oscillating_half_range_short": {j["case"]: j["half_short"] for j in judged
                                                if j["outcome"] == "oscillating" and j["half_short"]}}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n\nOut by the rule: " + "; ".join(f"{name} ({why})" for name, why
                                                                      in left_out) + "\n\n```json\n"
                   + json.dumps(summary, indent=1) + "\n```\n")
    out.with_suffix(".json").write_text(json.dumps(judged, indent=1))
    print("\n".join(lines))
    print(json.dumps(summary, indent=1))


def converging_table(rows_path: Path, references: Path, arrays: Path, out: Path) -> None:
    """A converging set: each case against its own run (the reference's first iteration meeting the
    criterion): never more iterations; where the stop on the answer came first, the true error there."""
    lines = ["| case | outcome | iterations | own (criterion) | ratio | true error (max) | estimate (max) | "
             "estimate >= true |", "|---|---|---|---|---|---|---|---|"]
    judged = []
    for row in (json.loads(line) for line in rows_path.read_text().splitlines()):
        reference = json.loads((references / f"{row['case']}.json").read_text())
        own = reference["criterion_met_at"]
        found = judge_row(row, reference, arrays)
        found["own"] = own
        judged.append(found)
        lines.append(f"| {row['case']} | {row['outcome']} | {row['iterations']} | {own} | "
                     f"{_f(row['iterations'] / own if own else None, '.3f')} | {_f(found['true_max'])} | "
                     f"{_f(found['estimate_max'])} | {found['held']}/{len(found['pairs'])} |")
    pairs = [p for j in judged for p in j["pairs"]]
    ratios = [e / t for e, t in pairs if t > 0]
    early = [j for j in judged if j["outcome"] in ("settled", "oscillating")]
    summary = {"cases": len(judged),
               "more_iterations_than_own": [j["case"] for j in judged
                                            if j["own"] and j["iterations"] > j["own"]],
               "stopped_on_the_answer_first": [j["case"] for j in early],
               "of_those_true_error_above_tolerance": [j["case"] for j in early
                                                       if (j["true_max"] or 0) > TOLERANCE],
               "pairs": len(pairs),
               "share_held": sum(e >= t for e, t in pairs) / len(pairs) if pairs else None,
               "median_estimate_over_true": statistics.median(ratios) if ratios else None,
               **resolved_sharpness(pairs)}
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n\n```json\n" + json.dumps(summary, indent=1) + "\n```\n")
    print("\n".join(lines))
    print(json.dumps(summary, indent=1))


def resolved_sharpness(pairs: list[tuple[float, float]]) -> dict[str, float | int | None]:
    """The sharpness over the pairs whose true error is resolved (at least RESOLVED)."""
    ratios = [e / t for e, t in pairs if t >= RESOLVED]
    return {"pairs_resolved": len(ratios),
            "median_estimate_over_true_resolved": statistics.median(ratios) if ratios else None}


def _f(value: float | None, spec: str = ".1e") -> str:
    return "" if value is None or (isinstance(value, float) and math.isnan(value)) else format(value, spec)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    go = sub.add_parser("run")
    go.add_argument("cases", type=Path)
    go.add_argument("--out", type=Path, required=True)
    go.add_argument("--rows", type=Path, required=True)
    go.add_argument("--only", nargs="+")
    tab = sub.add_parser("table")
    tab.add_argument("--rows", type=Path, required=True)
    tab.add_argument("--references", type=Path, required=True)
    tab.add_argument("--arrays", type=Path, required=True)
    tab.add_argument("--table", type=Path, required=True)
    tab.add_argument("--converging", action="store_true",
                     help="a converging set: each case against its own run, no fresh-set rule")
    args = parser.parse_args()
    if args.command == "run":
        run(args.cases, args.out, args.rows, args.only)
    elif args.converging:
        converging_table(args.rows, args.references, args.arrays, args.table)
    else:
        table(args.rows, args.references, args.arrays, args.table)


if __name__ == "__main__":
    main()
