"""``jaxsimrl solve --compare`` on OpenFOAM's simpleFoam tutorials (their own mesh and settings).

    .venv/bin/python benchmarks/bench_solve.py pitzDaily airFoil2D backwardFacingStep2D --out /tmp/bench

(``--policy RUN`` solves with a train-foam run's policy instead of the shipped controller; ``--controller
residual-rule`` or ``bandit`` with a no-training rule, jaxsimrl.apps.foam.solve.rules; ``--compare-constant U
P T`` also runs those constant factors, a third solver beside the two: wall times are then shared three ways
on a 2-core machine, iterations are not.)

Prints one row per case: iterations and wall time of the controlled run and of the case's own settings,
their ratios, solve's overhead beyond the solver's own work (and its fixed cost in seconds, with the
phases of solve.json), whether a fallback fired, and whether the two converged results agree (the worst
field and function-object value; the whole ``agreement`` of solve.json is in the row). Nothing is
tuned on these cases. Appends the rows as JSON lines to OUT/rows.jsonl.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.apps.foam.solve.agreement import summary_line
from jaxsimrl.apps.foam.solve.controller import DEFAULT_CONTROLLER
from jaxsimrl.apps.foam.solve.rules import RULES

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")


def bench(name: str, root: Path, policy: Path | None = None, rule: str | None = None,
          constant: list[float] | None = None) -> dict:
    """Solve one tutorial (a fresh copy) with --compare (and --compare-constant ``constant``), by
    ``policy`` (a train-foam run; default: the shipped controller) or the no-training ``rule``; its row."""
    case = root / name
    shutil.rmtree(case, ignore_errors=True)
    shutil.rmtree(root / f"{name}.solved", ignore_errors=True)
    shutil.copytree(TUTORIALS / name, case)
    policy = policy if policy is not None or rule is not None else DEFAULT_CONTROLLER  # the shipped one
    data = solve_case(case, root / f"{name}.solved", policy=policy, compare=True, rule=rule,
                      compare_constant=constant).data
    result, own = data["result"], data["compare"]["own"]
    fixed = data["compare"].get("constant")
    return {"case": name, "algorithm": data["settings"]["algorithm"], "controller": rule or "learned",
            "converged": result["converged"],
            "iterations": result["iterations"],
            "wall_s": round(result["wall_time_s"], 2), "own_converged": own["converged"],
            "own_iterations": own["iterations"], "own_wall_s": round(own["wall_time_s"], 2),
            "ratio_iterations": round(own["ratio_iterations"], 3),
            "ratio_wall": round(own["ratio_wall_time"], 3),
            "ratio_cpu": round(own["ratio_solver_cpu_time"], 3),
            "overhead_pct": _percent(result["overhead_fraction"]),
            # solve's fixed cost: its wall time beyond the controlled solver's busy time, and its phases
            "fixed_s": round(result["wall_time_s"] - result["solver_busy_s"], 2),
            "phases": {name: round(value, 2) for name, value in result.get("phases", {}).items()},
            "fallback": [event["kind"] for event in data["fallback"]], "fields_from": result["fields_from"],
            "agreement_line": summary_line("own", own["agreement"]), "agreement": own["agreement"],
            **({} if fixed is None else {"constant": constant, "constant_converged": fixed["converged"],
                                         "constant_iterations": fixed["iterations"]})}


def _percent(fraction: float | None) -> float | None:
    return None if fraction is None else round(100 * fraction, 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="+")
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--policy", type=Path, default=None,
                        help="a train-foam run directory (default: the shipped controller)")
    parser.add_argument("--controller", choices=("learned", *RULES), default="learned")
    parser.add_argument("--compare-constant", type=float, nargs=3, metavar="F", default=None)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.cases:
        row = bench(name, args.out, args.policy, None if args.controller == "learned" else args.controller,
                    args.compare_constant)
        print(json.dumps(row), flush=True)
        with open(args.out / "rows.jsonl", "a") as rows:
            rows.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
