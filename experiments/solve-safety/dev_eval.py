# SPDX-License-Identifier: GPL-3.0-or-later
"""Run ``jaxsimrl solve`` with a no-training rule on development cases, its module constants overridden,
and append one row per case: iterations, convergence, solver CPU, linear-solver iterations, the factors of
every step and where the rule went back to the case's own (issue 46's design loop; development cases
only: heldout-v1 and the solve benchmark's tutorials, never heldout-v2).

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/solve-safety/dev_eval.py \
        runs/heldout-v1/contraction2D runs/dev/pitzDaily --rule guarded --set SWITCH_DECADES=1.5 \
        --out experiments/solve-safety/dev.jsonl
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from pathlib import Path

from trajectories import per_iteration

from jaxsimrl.apps.foam.solve import rules, solve_case


def row(case: Path, rule: str, overrides: dict[str, float], scratch: Path) -> dict:
    out = scratch / f"{case.name}.solved"
    report = solve_case(case, out, rule=rule, compare=False, spread=False, step_timeout_s=600)
    data = report.data
    cpu, linear = per_iteration(out / "log.simpleFoam")
    return {"case": case.name, "rule": rule, "overrides": overrides, "converged": report.converged,
            "iterations": report.iterations, "cpu_s": round(data["result"]["solver_cpu_time_s"], 2),
            "linear": linear[-1] if linear else None, "fields_from": data["result"]["fields_from"],
            "fallback": [event["kind"] for event in data["fallback"]],
            "steps": [[step["from_iteration"], [round(a, 4) for a in step["action"]]]
                      for step in data["steps"]]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="+", type=Path)
    parser.add_argument("--rule", default="guarded", choices=sorted(rules.RULES))
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    overrides = {name: float(value) for name, value in (item.split("=") for item in args.set)}
    for name, value in overrides.items():
        assert hasattr(rules, name), name
        setattr(rules, name, type(getattr(rules, name))(value))
    for case in args.cases:
        scratch = Path(tempfile.mkdtemp(prefix="dev-eval-"))
        try:
            found = row(case.resolve(), args.rule, overrides, scratch)
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
        print(json.dumps({k: v for k, v in found.items() if k != "steps"}), flush=True)
        with open(args.out, "a") as out:
            out.write(json.dumps(found) + "\n")


if __name__ == "__main__":
    main()
