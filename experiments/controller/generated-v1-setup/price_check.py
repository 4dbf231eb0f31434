# SPDX-License-Identifier: GPL-3.0-or-later
"""What does a factor cost per SIMPLE iteration, with the machine's load taken out? A controlled check:
one case run to its criterion by plain simpleFoam at fixed factors (its own, then each named factor
raised by DELTA; with --function-objects also the own factors with the bridge's state function
objects), the settings alternated round after round so that the load falls alike on each, and
for each setting the median solver CPU per iteration and linear-solver iterations per iteration.

    python experiments/controller/generated-v1-setup/price_check.py runs/generated-val/bump-2 \
        --raise turbulence p --rounds 4 --out price.jsonl
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from foam_bridge import LogParser, find_openfoam

#: fvSolution's relaxation entries, as the generator writes them (foam_bridge/_generator.py).
_ENTRY = {"p": r"(fields\s*\{\s*p\s+)([0-9.]+)", "U": r"(equations\s*\{\s*U\s+)([0-9.]+)",
          "turbulence": r"(equations\s*\{\s*U\s+[0-9.]+;\s*\"\(k\|epsilon\|omega\)\"\s+)([0-9.]+)"}


def set_factor(fv_solution: Path, factor: str, value: float) -> None:
    text = fv_solution.read_text()
    new, count = re.subn(_ENTRY[factor], lambda m: f"{m.group(1)}{value:.4g}", text)
    if count != 1:
        raise SystemExit(f"{fv_solution}: no single relaxation entry for {factor}")
    fv_solution.write_text(new)


def own_factor(fv_solution: Path, factor: str) -> float:
    return float(re.search(_ENTRY[factor], fv_solution.read_text()).group(2))


#: The state function objects foam_bridge runs every iteration of a controlled run
#: (foam_bridge._episode_case._function_objects), for ``--function-objects``.
_BRIDGE_FUNCTIONS = """
functions
{
    magSqrU { type magSqr; libs ("libfieldFunctionObjects.so"); field U; result magSqrU;
        executeControl timeStep; executeInterval 1; writeControl none; }
    cells { type volFieldValue; libs ("libfieldFunctionObjects.so"); fields (magSqrU); operation average;
        regionType all; executeControl timeStep; executeInterval 1; writeControl timeStep; writeInterval 1;
        log true; writeToFile false; writeFields false; }
    inlet { type surfaceFieldValue; libs ("libfieldFunctionObjects.so"); fields (magSqrU);
        operation average; regionType patch; name inlet; surfaceFormat none; executeControl timeStep;
        executeInterval 1; writeControl timeStep; writeInterval 1; log true; writeToFile false;
        writeFields false; }
}
"""
#: A setting's key that adds _BRIDGE_FUNCTIONS instead of changing a factor.
_FUNCTIONS = "functions"


def run_once(case: Path, settings: dict[str, float], work: Path) -> dict:
    run_dir = work / "run"
    if run_dir.exists():
        shutil.rmtree(run_dir)
    shutil.copytree(case, run_dir, ignore=shutil.ignore_patterns("log.*", "processor*"))
    for factor, value in settings.items():
        if factor == _FUNCTIONS:
            with (run_dir / "system" / "controlDict").open("a") as control:
                control.write(_BRIDGE_FUNCTIONS)
        else:
            set_factor(run_dir / "system" / "fvSolution", factor, value)
    openfoam = find_openfoam()
    with (run_dir / "log.simpleFoam").open("w") as log:
        subprocess.run([openfoam.executable("simpleFoam"), "-case", str(run_dir)], stdout=log,
                       stderr=subprocess.STDOUT, env=openfoam.environment(run_dir), check=False)
    parser = LogParser(cells_function="", inlet_function="")
    parser.feed((run_dir / "log.simpleFoam").read_text())
    parser.finish()
    iterations = parser.completed
    return {"iterations": iterations, "cpu_s": parser.execution_time,
            "linear_per_iteration": parser.linear_iterations / max(iterations, 1)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case", type=Path)
    ap.add_argument("--raise", dest="raised", nargs="*", default=["turbulence"], choices=sorted(_ENTRY))
    ap.add_argument("--delta", type=float, default=0.1)
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--function-objects", action="store_true",
                    help="also the own factors with the bridge's per-iteration state function objects")
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    fv = args.case / "system" / "fvSolution"
    settings = {"own": {}}
    for factor in args.raised:
        value = min(own_factor(fv, factor) + args.delta, 1.0)
        settings[f"{factor} {value:.2f}"] = {factor: value}
    if args.function_objects:
        settings["own + function objects"] = {_FUNCTIONS: 1.0}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for round_ in range(args.rounds):
            for label, setting in settings.items():
                measured = run_once(args.case, setting, Path(tmp))
                row = {"case": args.case.name, "setting": label, "round": round_, **measured}
                rows.append(row)
                print(json.dumps(row), flush=True)
    if args.out:
        with args.out.open("a") as out:
            out.writelines(json.dumps(row) + "\n" for row in rows)
    own = [r["cpu_s"] / r["iterations"] for r in rows if r["setting"] == "own" and r["iterations"] > 0]
    for label in settings:
        mine = [r for r in rows if r["setting"] == label and r["iterations"] > 0]  # a failed start: none
        per_it = np.median([r["cpu_s"] / r["iterations"] for r in mine])
        print(f"{args.case.name} {label:>16}: {np.median([r['iterations'] for r in mine]):.0f} iterations, "
              f"{1e3 * per_it:.2f} ms CPU/iteration ({per_it / np.median(own):.2f}x own), "
              f"{np.median([r['linear_per_iteration'] for r in mine]):.1f} linear iterations/iteration")


if __name__ == "__main__":
    main()
