# SPDX-License-Identifier: GPL-3.0-or-later
"""Per-iteration trajectories of development cases under constant factors: what a do-no-harm default has to
read, before any controller is designed on it (issue 46).

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/solve-safety/trajectories.py \
        runs/heldout-v1/bump2D ... --out experiments/solve-safety/trajectories.jsonl

For every case: its own settings, the top of the box a controller may use (SIMPLEC: (0.95, 1.0, 0.95);
plain SIMPLE: 1.25x its own factors), the point half-way, and its own alpha_u with the box's top for the
pressure and turbulence factors ("fixed"), each run once by plain ``simpleFoam`` to the
case's own criterion and budget (jaxsimrl.apps.foam.solve.own.run_own, as ``--compare-constant`` runs it).
One JSON line per run: the factors, the outcome, and per iteration the distance to the criterion (the worst
field's decades above its threshold, as solve's watchdog reads it), the solver's CPU seconds and the linear
solvers' iterations (from the run's log). Development cases only (heldout-v1 and the solve benchmark's
tutorials): never heldout-v2.
"""

from __future__ import annotations

import argparse
import json
import re
import tempfile
from pathlib import Path

from foam_bridge import criterion_distance, field_residual, find_openfoam, foamdict
from jaxsimrl.apps.foam.solve.own import run_own
from jaxsimrl.apps.foam.solve.settings import read_case_settings

#: The SIMPLEC box's top for a controller acting around the case's own factors (settings.SIMPLEC_TOP).
SIMPLEC_TOP = (0.95, 1.0, 0.95)
#: Plain SIMPLE's box top: this many times the case's own factors (foam_bridge's user-case box).
SIMPLE_TOP = 1.25

_TIME = re.compile(r"^Time = (\S+)")
_SOLVE = re.compile(r"Solving for (\w+), Initial residual = \S+, Final residual = \S+, No Iterations (\d+)")
_EXECUTION = re.compile(r"^ExecutionTime = (\S+) s")


def criterion_of(case: Path) -> dict[str, str | float]:
    """The case's SIMPLE.residualControl as written (keys may be patterns such as "(k|epsilon)")."""
    solution = foamdict.expand(find_openfoam(), case, "system/fvSolution")
    return {str(k): float(v) for k, v in solution.get("SIMPLE", {}).get("residualControl", {}).items()}


def resolved(criterion: dict[str, float], names: set[str]) -> dict[str, float]:
    """The criterion over the fields the log names (a pattern key matches every field it spells)."""
    bases = {name[:-1] if name[-1] in "xyz" and name[:-1] in ("U",) else name for name in names}
    found: dict[str, float] = {}
    for key, threshold in criterion.items():
        pattern = re.compile(key.strip('"') + r"\Z")
        for base in bases:
            if pattern.match(base):
                found[base] = threshold
    return found


def per_iteration(log: Path) -> tuple[list[float], list[int]]:
    """The solver's cumulative CPU seconds and linear iterations at the end of every iteration."""
    cpu, linear, total = [], [], 0
    for line in log.read_text(errors="replace").splitlines():
        if match := _SOLVE.search(line):
            total += int(match.group(2))
        elif match := _EXECUTION.match(line):
            cpu.append(float(match.group(1)))
            linear.append(total)
    return cpu, linear


def triples(case: Path) -> tuple[str, list[tuple[str, tuple[float, float, float] | None]]]:
    """The case's algorithm and the (label, factors) runs: own (None), half-way and the box's top."""
    settings = read_case_settings(case)
    own = tuple(1.0 if f is None else f for f in settings.factors)
    if settings.variant == "SIMPLEC":
        top = tuple(max(t, o) for t, o in zip(SIMPLEC_TOP, own, strict=True))
    else:
        top = tuple(min(SIMPLE_TOP * o, 0.95) for o in own)
    mid = tuple(round(0.5 * (o + t), 4) for o, t in zip(own, top, strict=True))
    # "fixed": alpha_u kept at its own (it alone moves the converged answer: the face fluxes depend on the
    # momentum matrix's relaxed diagonal), pressure and turbulence at the box's top
    fixed = (own[0], top[1], top[2])
    return settings.variant, [("own", None), ("mid", mid), ("top", top), ("fixed", fixed)]


def trajectory(case: Path, label: str, factors: tuple[float, float, float] | None, scratch: Path) -> dict:
    run = run_own(case, scratch / f"{case.name}-{label}", label, 1800.0, factors)
    criterion = resolved(criterion_of(case), {name for step in run.history for name in step})
    distance = [round(criterion_distance({name: field_residual(step, name) or float("nan")
                                          for name in criterion}, criterion), 4) for step in run.history]
    cpu, linear = per_iteration(Path(run.case) / "log.simpleFoam")
    return {"case": case.name, "label": label, "factors": factors, "converged": run.converged,
            "iterations": run.iterations, "cpu_s": round(run.cpu_time_s, 2), "error": run.error,
            "criterion": criterion, "distance": distance, "cpu": cpu, "linear": linear}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="+", type=Path)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--only", nargs="*", default=None, help="labels to run (own, mid, top, fixed)")
    args = parser.parse_args()
    for case in args.cases:
        algorithm, runs = triples(case)
        for label, factors in runs:
            if args.only and label not in args.only:
                continue
            with tempfile.TemporaryDirectory(prefix="trajectory-") as scratch:
                row = {"algorithm": algorithm, **trajectory(case.resolve(), label, factors, Path(scratch))}
            print(case.name, label, factors, row["converged"], row["iterations"], row["cpu_s"], flush=True)
            with open(args.out, "a") as out:
                out.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
