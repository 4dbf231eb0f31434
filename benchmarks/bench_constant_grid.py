"""Constant relaxation factors on an OpenFOAM tutorial: every (alpha_u, alpha_p) cell of a grid, the
turbulence fields at alpha_u, plain ``simpleFoam`` to the case's own residualControl.

    .venv/bin/python benchmarks/bench_constant_grid.py airFoil2D --alpha-u 0.7 0.7875 0.875 \
        --alpha-p 0.3 0.3375 0.375 --out benchmarks/results/rules-2026-12-03/grid-airFoil2D

What the box of a plain-SIMPLE case ([own / 2, 1.25 own], foam_bridge._user_case) lets a constant reach,
beside what solve's controllers reach (benchmarks/RESULTS_solve.md). A cell at alpha_u >= the case's own
needs no convergence check: its solver's own test already normalised at least as strictly as the case's.
Runs two cells at a time (one simpleFoam each); writes OUT/grid.jsonl (a row per cell) and prints a table.
"""

from __future__ import annotations

import argparse
import json
import shutil
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from jaxsimrl.apps.foam.solve.own import OwnRun, run_own

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")


def run_cell(name: str, root: Path, factors: tuple[float, float, float], timeout_s: float = 3600.0) -> OwnRun:
    """One plain run of tutorial ``name`` at constant ``factors`` (alpha_u, alpha_p, turbulence) in
    ``root``."""
    dest = root / "_".join(f"{f:g}" for f in factors)
    shutil.rmtree(dest, ignore_errors=True)
    return run_own(TUTORIALS / name, dest, "constant", timeout_s, factors)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", help="a tutorial of incompressible/simpleFoam")
    parser.add_argument("--alpha-u", type=float, nargs="+", required=True)
    parser.add_argument("--alpha-p", type=float, nargs="+", required=True)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    cells = [(u, p, u) for u in args.alpha_u for p in args.alpha_p]
    with tempfile.TemporaryDirectory() as scratch, ThreadPoolExecutor(2) as pool:
        runs = list(pool.map(lambda cell: run_cell(args.case, Path(scratch), cell), cells))
    rows = [{"case": args.case, "factors": list(cell), "converged": run.converged,
             "iterations": run.iterations, "error": run.error} for cell, run in zip(cells, runs, strict=True)]
    (args.out / "grid.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    print("alpha_u \\ alpha_p | " + " | ".join(f"{p:g}" for p in args.alpha_p))
    for u in args.alpha_u:
        cells_u = [r for r in rows if r["factors"][0] == u]
        print(f"{u:g} | " + " | ".join(str(r["iterations"]) + ("" if r["converged"] else " (not converged)")
                                       for r in cells_u))


if __name__ == "__main__":
    main()
