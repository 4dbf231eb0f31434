# SPDX-License-Identifier: GPL-3.0-or-later
"""Measure each prepared held-out case under its OWN settings (plain simpleFoam, nothing changed), one
run at a time, and append one JSON line per run to --out.

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/controller/heldout-v1/measure.py \
        runs/heldout-v1 --runs 2 --timeout 300 --out experiments/controller/heldout-v1/measurements.jsonl

Each run is on a fresh copy (the prepared case is never written to). Iterations and convergence are read
by the project's own log parser (foam_bridge._logparse): converged = its residualControl, or its own
runTimeControl, ended the run. A run past --timeout counts as not converged at the iterations it had done.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

from foamcase import cell_count, foam_env

from foam_bridge._logparse import LogParser
from foam_bridge._openfoam import find_openfoam
from foam_bridge._solver import run_to_end


def settings(case: Path) -> dict[str, object]:
    """What the case says of itself: algorithm (SIMPLEC when SIMPLE.consistent is on), RAS model, endTime."""
    solution = (case / "system" / "fvSolution").read_text()
    simple = solution[solution.index("SIMPLE"):]
    consistent = re.search(r"consistent\s+(\w+)\s*;", simple.split("relaxationFactors")[0])
    on = consistent is not None and consistent.group(1) in ("yes", "on", "true")
    model = re.search(r"RASModel\s+(\w+)\s*;", (case / "constant" / "turbulenceProperties").read_text())
    end = re.search(r"\nendTime\s+([0-9.e+]+)\s*;", (case / "system" / "controlDict").read_text())
    return {"algorithm": "SIMPLEC" if on else "SIMPLE", "turbulence_model": model.group(1) if model else None,
            "end_time": int(float(end.group(1))) if end else None, "cells": cell_count(case)}


def measure(case: Path, timeout_s: float) -> dict[str, object]:
    """One plain run of ``case`` on a scratch copy."""
    with tempfile.TemporaryDirectory(prefix=f"heldout-{case.name}-") as scratch:
        run = Path(scratch) / case.name
        shutil.copytree(case, run, symlinks=True)
        parser = LogParser("", "")
        try:
            code, wall = run_to_end(run, find_openfoam(), parser, timeout_s)
        except subprocess.TimeoutExpired:
            parser.feed((run / "log.simpleFoam").read_bytes())
            parser.finish()
            code, wall = None, timeout_s
        ended = parser.converged_at or parser.stopped_at
        return {"converged": ended is not None and code == 0, "iterations": ended or parser.completed,
                "wall_s": round(wall, 1), "cpu_s": round(parser.execution_time, 1), "exit_code": code,
                "stopped_by": parser.stopped_by, "error": parser.error or None}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", type=Path, help="the directory prepare.py built")
    parser.add_argument("--only", nargs="+", help="these cases only")
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--timeout", type=float, default=300.0, help="seconds per run")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args(argv)
    foam_env()  # fails early without OpenFOAM's environment
    for case in sorted(p for p in args.cases.iterdir() if (p / "system" / "controlDict").is_file()):
        if args.only and case.name not in args.only:
            continue
        for index in range(args.runs):
            row = {"case": case.name, "run": index, **settings(case), **measure(case, args.timeout),
                   "date": time.strftime("%Y-%m-%dT%H:%M:%S")}
            with args.out.open("a") as out:
                out.write(json.dumps(row) + "\n")
            print(json.dumps(row), flush=True)
            if row["exit_code"] is None:
                break  # past the timeout: a second run would say the same, at the same cost


if __name__ == "__main__":
    main()
