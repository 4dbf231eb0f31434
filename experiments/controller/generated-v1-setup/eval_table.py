# SPDX-License-Identifier: GPL-3.0-or-later
"""Issue 47's table from evaluate.py's rows: every case, losses included, then the issue's targets.

    python experiments/controller/generated-v1-setup/eval_table.py \\
        experiments/controller/generated-v3-eval/heldout-v2 [--policy-names seed0 seed1] > .../table.md

``--learned FILE ...``: learned runs made later (evaluate.py --learned-only) beside the same baselines; a
policy already in the rows is replaced, a new one added. Under the targets, the seeds' spread.

Each cell is iterations / own, solver CPU / own. A learned or rule run's CPU is over the own run made just
before it (the machine's load moves both); the plain runs (the generated family's constant, the per-case
oracle) are over the median of the case's own runs in rows.jsonl. Bold: over the issue's per-case bound
(1.10x own iterations, or CPU over max(1.10x, own + 0.5 s)); "not conv." where a run missed the criterion.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path
from typing import Any

RULES = ("residual-rule", "bandit", "random")


def own_runs(row: dict[str, Any]) -> list[dict[str, Any]]:
    """Every own run of a case's row (one before each learned and each rule run). main takes them from
    rows.jsonl before --learned joins later runs (another sitting's load: the plain runs' own must not
    move)."""
    return [run["own"] for run in (*row["learned"].values(), *(row[rule] for rule in RULES))]


def ratios(run: dict[str, Any], own: dict[str, Any]) -> tuple[float, float]:
    """(iterations / own, CPU / own). A run that missed the criterion the own run met counts as infinitely
    dear; where the own run missed it too both ran to the case's budget, and an oracle grid none of whose
    constants converged leaves the user with the own run."""
    if not run.get("converged") and own["converged"]:
        return float("inf"), float("inf")
    if "iterations" not in run:
        return 1.0, 1.0
    return run["iterations"] / own["iterations"], run["cpu_s"] / own["cpu_s"]


def versus(mine: float, theirs: float) -> float:
    """One CPU ratio over another (both over their own runs); two runs that both missed tie."""
    return 1.0 if mine == theirs == float("inf") else mine / theirs


def over_bound(run: dict[str, Any], own: dict[str, Any]) -> bool:
    its, cpu = ratios(run, own)
    return its > 1.10 or (cpu > 1.10 and run["cpu_s"] > own["cpu_s"] + 0.5)


def cell(run: dict[str, Any], own: dict[str, Any]) -> str:
    if not run.get("converged") and own["converged"]:
        return f"**not conv. ({run.get('iterations', 'grid')})**"
    its, cpu = ratios(run, own)
    text = f"{its:.2f} / {cpu:.2f}{'' if run.get('converged') else ' (not conv., as own)'}"
    return f"**{text}**" if over_bound(run, own) else text


def median_own(row: dict[str, Any]) -> dict[str, Any]:
    runs = row["own_runs"]
    return {"converged": all(r["converged"] for r in runs), "iterations": runs[0]["iterations"],
            "cpu_s": statistics.median(r["cpu_s"] for r in runs)}


def columns(rows: list[dict[str, Any]], names: list[str]) -> list[tuple[str, Any]]:
    """(heading, row -> (run, own)) for every column of the table."""
    policies = list(rows[0]["learned"])
    learned = [(f"learned {name}", lambda row, p=p: (row["learned"][p], row["learned"][p]["own"]))
               for name, p in zip(names, policies, strict=True)]
    rules = [(rule, lambda row, rule=rule: (row[rule], row[rule]["own"])) for rule in RULES]
    plain = [("family constant", lambda row: (row["constant"], median_own(row))),
             ("per-case oracle", lambda row: (row["oracle"], median_own(row)))]
    return [*learned, *rules, *plain]


def table(rows: list[dict[str, Any]], names: list[str]) -> str:
    cols = columns(rows, names)
    head = ["case", "algorithm", "own iterations", "own CPU s", *(name for name, _ in cols),
            "oracle's factors (grid CPU s)"]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for row in rows:
        own = median_own(row)
        oracle = row["oracle"]
        lines.append("| " + " | ".join([
            row["case"], row["algorithm"], f"{own['iterations']}{'' if own['converged'] else ' (not conv.)'}",
            f"{own['cpu_s']:.1f}", *(cell(*pick(row)) for _, pick in cols),
            f"{oracle.get('best') or '-'} ({oracle['grid_cpu_s']:.0f})"]) + " |")
    medians = [statistics.median(ratios(*pick(row))[k] for row in rows) for _, pick in cols for k in (0, 1)]
    lines.append("| **median** | | | | " + " | ".join(
        f"{medians[2 * k]:.2f} / {medians[2 * k + 1]:.2f}" for k in range(len(cols))) + " | |")
    losses = [sum(over_bound(*pick(row)) for row in rows) for _, pick in cols]
    lines.append("| **cases over the bound** | | | | " + " | ".join(map(str, losses)) + " | |")
    return "\n".join(lines)


def targets(rows: list[dict[str, Any]], names: list[str]) -> str:
    lines = ["| learned | median CPU / bandit's (<= 0.90) | median CPU / own (<= 0.85) | "
             "cases over the per-case bound (0) |", "|---|---|---|---|"]
    spread = []
    for name, policy in zip(names, rows[0]["learned"], strict=True):
        runs = [(row["learned"][policy], row["learned"][policy]["own"], row) for row in rows]
        bandit = [ratios(row["bandit"], row["bandit"]["own"])[1] for row in rows]
        vs_bandit = statistics.median(versus(ratios(run, own)[1], theirs)
                                      for (run, own, _), theirs in zip(runs, bandit, strict=True))
        vs_own = statistics.median(ratios(run, own)[1] for run, own, _ in runs)
        over = [row["case"] for run, own, row in runs if over_bound(run, own)]
        lines.append(f"| {name} | {vs_bandit:.2f} | {vs_own:.2f} | {len(over)}{': ' if over else ''}"
                     f"{', '.join(over)} |")
        spread.append((vs_bandit, vs_own, len(over)))
    if len(spread) > 1:
        low, high = (tuple(map(f, zip(*spread, strict=True))) for f in (min, max))
        lines.append(f"| spread over the {len(spread)} policies (min-max) | {low[0]:.2f}-{high[0]:.2f} | "
                     f"{low[1]:.2f}-{high[1]:.2f} | {low[2]}-{high[2]} |")
    return "\n".join(lines)


#: Where a run that missed the criterion the own run met is drawn (CPU / own), as a cross: right of
#: every ratio measured so far (the largest: the bandit on heldout-v3's porousLow, 3.56x).
MISSED_AT = 4.0


def figure(rows: list[dict[str, Any]], names: list[str], path: Path) -> None:
    """Solver CPU / own per case (a row each) and controller (a colour each), log scale; crosses at the right
    edge: runs that missed the criterion. The issue's bound (1.10x) and its median target (0.85x) dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = columns(rows, names)
    fig, ax = plt.subplots(figsize=(9, 0.45 * len(rows) + 1.5))
    for k, (name, pick) in enumerate(cols):
        cpu = [ratios(*pick(row))[1] for row in rows]  # inf: missed the criterion the own run met
        y = [j + (k - (len(cols) - 1) / 2) * 0.08 for j in range(len(rows))]
        missed = [c == float("inf") for c in cpu]
        ax.scatter([c for c, m in zip(cpu, missed, strict=True) if not m],
                   [v for v, m in zip(y, missed, strict=True) if not m], color=f"C{k}", s=18, label=name)
        ax.scatter([MISSED_AT] * sum(missed), [v for v, m in zip(y, missed, strict=True) if m], color=f"C{k}",
                   marker="x")
    for x, style in ((1.0, "-"), (1.10, "--"), (0.85, ":")):
        ax.axvline(x, color="k", lw=0.8, ls=style)
    ax.set_xscale("log")
    ax.set_yticks(range(len(rows)), [row["case"] for row in rows])
    ax.invert_yaxis()
    ax.set_xlabel(f"solver CPU / the case's own (x at {MISSED_AT:g}: missed the criterion)")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=4)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def read(path: Path) -> list[dict[str, Any]]:
    return [json.loads(line) for line in path.read_text().splitlines() if line]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path, help="evaluate.py's --out")
    parser.add_argument("--policy-names", nargs="+", help="a short name per --policy, in order")
    parser.add_argument("--learned", type=Path, nargs="+", help="evaluate.py --learned-only's rows, "
                        "replacing or adding learned columns (default DIRECTORY/learned-rows.jsonl where it "
                        "exists)")
    parser.add_argument("--figure", type=Path, help="also draw the CPU ratios here (a PNG)")
    args = parser.parse_args()
    rows = [{**row, "own_runs": own_runs(row)} for row in read(args.directory / "rows.jsonl")]
    later = args.learned or [args.directory / "learned-rows.jsonl"]  # seeds (or runs) evaluated later
    for extra in (extra for path in later if path.exists() for extra in read(path)):
        next(row for row in rows if row["case"] == extra["case"])["learned"].update(extra["learned"])
    names = args.policy_names or [Path(p).name for p in rows[0]["learned"]]
    print(table(rows, names) + "\n\n" + targets(rows, names))
    if args.figure:
        figure(rows, names, args.figure)


if __name__ == "__main__":
    main()
