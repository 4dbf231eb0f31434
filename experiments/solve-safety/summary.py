# SPDX-License-Identifier: GPL-3.0-or-later
"""The development table of the solve-safety study: every lever measured on the development cases, as
iterations to the case's own criterion over its own settings' (from trajectories.jsonl, guarded-dev.jsonl,
pressure.jsonl and lean.jsonl beside this file; heldout-v1's heldout.json for an own run measured there).

    python experiments/solve-safety/summary.py > experiments/solve-safety/table.md
"""

from __future__ import annotations

import json
from collections import defaultdict
from pathlib import Path

HERE = Path(__file__).resolve().parent
HELDOUT_V1 = HERE.parent / "controller" / "heldout-v1" / "heldout.json"
LEVERS = ("mid", "top", "fixed", "guarded", "p relTol 0.3", "p relTol 0.5", "lean")


def rows(name: str) -> list[dict]:
    return [json.loads(line) for line in (HERE / name).read_text().splitlines() if line.strip()]


def ratio(run: dict, own: int | None) -> str:
    if not run.get("converged"):
        return f"not converged ({run.get('iterations')})" if not run.get("error") else "failed"
    return "-" if not own else f"{run['iterations'] / own:.2f}"


def table() -> str:
    own: dict[str, int] = {}
    cells: dict[str, dict[str, str]] = defaultdict(dict)
    for run in rows("trajectories.jsonl"):
        if run["label"] == "own":
            own[run["case"]] = run["iterations"]
    for run in rows("pressure.jsonl") + rows("lean.jsonl"):
        if run["rel_tol"] is None and run["converged"]:
            own.setdefault(run["case"], run["iterations"])
    for case in json.loads(HELDOUT_V1.read_text())["cases"]:  # own runs measured when the set was fixed
        if case.get("converged"):
            own.setdefault(case["name"], case["iterations"])
    for run in rows("trajectories.jsonl"):
        if run["label"] != "own":
            cells[run["case"]][run["label"]] = ratio(run, own.get(run["case"]))
    for run in rows("guarded-dev.jsonl"):
        cells[run["case"]]["guarded"] = ratio(run, own.get(run["case"]))
    for run in rows("pressure.jsonl") + rows("lean.jsonl"):
        if run["rel_tol"] is not None and run["rep"] == 0:
            label = "lean" if run["rel_tol"] == "lean" else f"p relTol {run['rel_tol']:g}"
            cells[run["case"]][label] = ratio(run, own.get(run["case"]))
    lines = ["| case | own iterations | " + " | ".join(LEVERS) + " |", "|---" * (len(LEVERS) + 2) + "|"]
    for case in sorted(cells):
        lines.append(f"| {case} | {own.get(case, '-')} | "
                     + " | ".join(cells[case].get(lever, "") for lever in LEVERS) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    print(table())
