# SPDX-License-Identifier: GPL-3.0-or-later
"""The table of one evaluated set (evaluate.py's DIR/rows.jsonl): every case, losses included.

    python experiments/solve-safety/report.py experiments/solve-safety/eval-heldout-v2 > .../table.md

Per case: the default's iterations and solver CPU against the case's own (CPU: the median of 3 alternated
pairs where the own run takes under 20 s, else the --compare run's), whether its answer agrees with the
own run's (the same run: the default is the own run), the spread of two legitimate runs (own and alpha_u
0.05 off: the worst field) and whether the criterion fixes the answer (every field within the larger of
its tolerance and 1 %, as jaxsimrl.apps.foam.solve.agreement.measure_spread decides it), then each
opt-in run beside it (iterations / own, solver CPU / own, and where it has a detector, when it fired and
its latency from the first step the run fell behind its own). Then the targets of issue 46 for the
default.
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path
from typing import Any

from jaxsimrl.apps.foam.solve.agreement import SETTLED

OPT_IN = ("bandit", "constant", "guarded", "lean")


def _worst(values: dict[str, float] | None) -> str:
    if not values:
        return "-"
    name, value = max(values.items(), key=lambda item: item[1])
    return f"{name} {100 * value:.2g} %"


def _spread(row: dict[str, Any]) -> str:
    spread = row.get("spread") or {}
    if not spread.get("measured"):
        return f"not measured ({spread.get('reason')})"
    fields = spread.get("fields", {})
    allowed = max((row.get("tolerance") or {}).get("fields", 0.0), SETTLED)
    settled = all(value <= allowed for value in fields.values())
    return f"{_worst(fields)}; {'fixed' if settled else '**uncertain**'}"


def _opt_in(row: dict[str, Any], name: str) -> str:
    run = row.get(name)
    if run is None:
        return ""
    own = row["own"]
    if not run["converged"]:
        return f"**not converged ({run['iterations']})**"
    text = f"{run['iterations'] / own['iterations']:.2f} / {run['cpu_s'] / own['cpu_s']:.2f}"
    detector = run.get("detector") or {}
    if detector.get("fired_at") is not None:
        latency = detector.get("latency")
        text += f" (fired {detector['fired_at']}{'' if latency is None else f', +{latency}'}" \
                f"{', false' if detector.get('false_fire') else ''})"
    ratio = run["iterations"] / own["iterations"]
    return f"**{text}**" if ratio > 1.10 else text


def table(rows: list[dict[str, Any]]) -> str:
    present = [name for name in OPT_IN if any(name in row for row in rows)]
    head = ["case", "algorithm", "own iterations", "own CPU s", "default iterations / own",
            "default CPU / own", "agrees with own", "spread (own vs alpha_u nudged)",
            *(f"{name}: iterations / CPU vs own" for name in present)]
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for row in rows:
        own = row["own"]
        converged = "" if own["converged"] else " (not conv.)"
        pairs = " (3 pairs)" if "cpu_pairs" in row else ""
        cells = [row["case"], row["algorithm"], f"{own['iterations']}{converged}", f"{own['cpu_s']:.1f}",
                 f"{row['iteration_ratio']:.3f}", f"{row.get('cpu_ratio', float('nan')):.3f}{pairs}",
                 {True: "yes", False: "**no**", None: "-"}[row["agree"]], _spread(row),
                 *(_opt_in(row, name) for name in present)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def targets(rows: list[dict[str, Any]]) -> str:
    worst_it = max(row["iteration_ratio"] for row in rows)
    over_cpu = [row["case"] for row in rows if row.get("cpu_ratio", 0) > 1.10
                and row.get("cpu_ratio", 0) * row["own"]["cpu_s"] > row["own"]["cpu_s"] + 0.5]
    median_cpu = statistics.median(row["cpu_ratio"] for row in rows if "cpu_ratio" in row)
    return "\n".join([
        "| target (issue 46, the default) | wanted | measured |", "|---|---|---|",
        f"| iterations / own, every case | <= 1.10 | worst {worst_it:.3f} |",
        f"| solver CPU, every case | <= max(1.10x, own + 0.5 s) | "
        f"{'met' if not over_cpu else 'over on ' + ', '.join(over_cpu)} |",
        f"| median solver CPU / own | <= 0.85 (heldout-v2) | {median_cpu:.3f} |"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("directory", type=Path)
    args = parser.parse_args()
    rows = [json.loads(line) for line in (args.directory / "rows.jsonl").read_text().splitlines() if line]
    print(table(rows) + "\n\n" + targets(rows))


if __name__ == "__main__":
    main()
