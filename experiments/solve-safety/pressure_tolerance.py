# SPDX-License-Identifier: GPL-3.0-or-later
"""Does a looser pressure solve cost a case outer iterations? The case's own settings against the same
with its pressure solver's relTol raised, each a plain ``simpleFoam`` run to its own criterion, alternated
``--reps`` times (solver CPU on a shared machine is noisy; iterations and linear iterations are exact).

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/solve-safety/pressure_tolerance.py \
        runs/heldout-v1/contraction2D ... --rel-tol 0.3 0.5 --out experiments/solve-safety/pressure.jsonl

The relaxed equations' fixed point does not depend on how far each linear solve goes (only on the
relaxation of U: jaxsimrl.apps.foam.solve.rules), so the converged answer is the case's own; what moves is
the work per iteration and possibly the iterations. Development cases only (issue 46).
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from pathlib import Path

from trajectories import per_iteration

from foam_bridge import find_openfoam, foamdict
from jaxsimrl.apps.foam.solve.own import run_own
from jaxsimrl.apps.foam.solve.solvers import make_lean

#: Every field a simpleFoam case of these sets may solve (make_lean skips those it has no solver for).
FIELDS = ("p", "U", "k", "epsilon", "omega", "nuTilda", "ReThetat", "gammaInt")


def pressure_solver(case: Path) -> tuple[str, dict]:
    """(the pressure field's name, its solver dictionary as OpenFOAM resolves it)."""
    solvers = foamdict.expand(find_openfoam(), case, "system/fvSolution")["solvers"]
    for name in ("p", "p_rgh"):
        try:
            return name, dict(foamdict.lookup(solvers, name))
        except KeyError:
            continue
    raise KeyError(f"{case}: no pressure solver")


def with_rel_tol(case: Path, rel_tol: float) -> None:
    """Append a ``solvers`` entry for the pressure field: its own solver dictionary, relTol replaced (an
    exact key wins over the case's pattern keys, and OpenFOAM merges the two ``solvers`` dictionaries)."""
    name, entry = pressure_solver(case)
    entry["relTol"] = rel_tol
    body = "".join(f"        {key} {value};\n" for key, value in entry.items() if not isinstance(value, dict))
    with open(case / "system" / "fvSolution", "a") as out:
        out.write(f"\nsolvers\n{{\n    {name}\n    {{\n{body}    }}\n}}\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", nargs="+", type=Path)
    parser.add_argument("--rel-tol", nargs="*", type=float, default=[0.3, 0.5])
    parser.add_argument("--reps", type=int, default=2)
    parser.add_argument("--lean", action="store_true", help="also solve's lean linear solves "
                        "(jaxsimrl.apps.foam.solve.solvers.make_lean: pressure and every other field)")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    for case in (case.resolve() for case in args.cases):
        own_rel_tol = pressure_solver(case)[1].get("relTol")
        for rep in range(args.reps):
            for rel_tol in [None, *args.rel_tol, *(["lean"] if args.lean else [])]:
                with tempfile.TemporaryDirectory(prefix="ptol-") as scratch:
                    source = Path(scratch) / case.name
                    shutil.copytree(case, source, symlinks=True)
                    if rel_tol == "lean":
                        make_lean(source, FIELDS)
                    elif rel_tol is not None:
                        with_rel_tol(source, rel_tol)
                    run = run_own(source, Path(scratch) / "run", "own", 3600.0)
                    cpu, linear = per_iteration(Path(run.case) / "log.simpleFoam")
                row = {"case": case.name, "rel_tol": rel_tol, "own_rel_tol": own_rel_tol, "rep": rep,
                       "converged": run.converged, "iterations": run.iterations,
                       "cpu_s": round(run.cpu_time_s, 2), "linear": linear[-1] if linear else None,
                       "error": run.error[:200]}
                print(json.dumps(row), flush=True)
                with open(args.out, "a") as out:
                    out.write(json.dumps(row) + "\n")


if __name__ == "__main__":
    main()
