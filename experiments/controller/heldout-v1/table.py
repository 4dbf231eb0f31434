# SPDX-License-Identifier: GPL-3.0-or-later
"""Write heldout.json, the fixed held-out list: each case's description (here), its own settings'
measurements (measurements.jsonl, from measure.py: median wall of its runs) and whether it is in the
evaluation set; the tutorials left out, with why; the date, the machine and the OpenFOAM version.

    .venv/bin/python experiments/controller/heldout-v1/table.py

A case is in the set when its own settings converge within its own endTime in every run, in under
BUDGET_S of wall time, and its geometry is none of the training bases'.
"""

from __future__ import annotations

import json
import os
import re
import statistics
import subprocess
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
SIMPLEFOAM = "incompressible/simpleFoam/"
BUDGET_S = 180.0

#: name -> (source, geometry, geometry shared with a training base or None).
CASES = {
    "bump2D": (SIMPLEFOAM + "bump2D", "2-D bump in a channel (NASA TMR bump), symmetry top", None),
    "pipeCyclic": (SIMPLEFOAM + "pipeCyclic", "3-D 90-degree sector of a straight pipe, swirling inlet, "
                   "rotational cyclicAMI sides", None),
    "rotorDisk": (SIMPLEFOAM + "rotorDisk", "3-D box with a rotor disk (fvOptions momentum source) in a "
                  "cylindrical zone", None),
    "simpleCar": (SIMPLEFOAM + "simpleCar", "2-D car silhouette in a channel (blocked cells removed)", None),
    "squareBend": (SIMPLEFOAM + "squareBend", "3-D square duct with a 90-degree bend (mesh halved)", None),
    "turbineSiting": (SIMPLEFOAM + "turbineSiting", "3-D terrain (snappyHexMesh) with two actuator-disk "
                      "turbines", None),
    "turbulentFlatPlate": (SIMPLEFOAM + "turbulentFlatPlate", "2-D zero-pressure-gradient flat plate "
                           "(tutorial's level-3 mesh, y+ 1)", "T3A (flat plate)"),
    "cavityRAS": ("built from incompressible/pisoFoam/RAS/cavity", "2-D lid-driven square cavity, Re 1e4",
                  None),
    "planarDiffuser": ("built", "2-D asymmetric planar diffuser, 10 degrees, area ratio 4.7, Re 2e4", None),
    "channelRib": ("built", "2-D channel with a square rib on one wall (0.2 of the height), Re 1e5", None),
    "tJunctionSteady": ("built from incompressible/pimpleFoam/RAS/TJunction", "3-D T-junction of square "
                        "ducts, velocity inlet, outlets at two pressures", None),
    "elbowRAS": ("built from incompressible/icoFoam/elbow", "2-D elbow with a side inlet (Fluent mesh, "
                 "triangles), Re 1e5", None),
    "bend2D": ("built", "2-D 90-degree channel bend (radius ratio 2), Re 1e5", None),
    "contraction2D": ("built", "2-D planar contraction (nozzle), area ratio 4, Re 1e5", None),
}

#: What the runs showed of the cases left out (from their logs), beyond the verdict.
NOTES = {
    "cavityRAS": "residuals stall from ~1000 iterations at epsilon 3.1e-4, p 1.8e-4, k 1.1e-4 (1e-4 asked)",
    "bend2D": "residuals stall from ~300 iterations at p 4.7e-4, omega 3.0e-4, k 2.4e-4 (1e-4 asked)",
    "elbowRAS": "k and epsilon bounded from the first iterations on the coarse triangular mesh; "
                "SIGFPE at iteration 972",
    "tJunctionSteady": "its first build (total-pressure inlet held at 40) crashed at iteration 10 (SIGFPE); "
                       "with a velocity inlet it runs but does not converge",
    "rotorDisk": "the slowest in: 130 and 190 s (median 160 s) on the shared machine, 84-99 s of CPU",
}

#: Tutorials not built at all: name -> why.
NOT_BUILT = {
    "windAroundBuildings": "185 237 cells (snappyHexMesh, measured); 1.3 s an iteration here (measured on 6 "
                           "iterations), its 400 iterations ~9 min a run: over the ~3 min budget",
    "mixerVessel2D": "its blockMeshDict is made by m4, which is not installed (an 800-line macro file); "
                     "it also has no residualControl",
    "motorBike": "325 703 cells after castellation alone (measured: serial snappyHexMesh without snap and "
                 "layers, 44 s; its layer adds more), 1.8x windAroundBuildings' mesh: ~2.3 s an iteration "
                 "here, its 500 iterations ~20 min a run, far over the budget",
}


def own(rows: list[dict]) -> dict:
    """One case's runs: converged in every run, iterations (median), median wall and CPU seconds."""
    last = rows[-1]
    return {"algorithm": last["algorithm"], "turbulence_model": last["turbulence_model"],
            "cells": last["cells"], "end_time": last["end_time"],
            "converged": all(r["converged"] for r in rows),
            "iterations": int(statistics.median(r["iterations"] for r in rows)),
            "iterations_runs": [r["iterations"] for r in rows],
            "wall_s": round(statistics.median(r["wall_s"] for r in rows), 1),
            "wall_s_runs": [r["wall_s"] for r in rows],
            "cpu_s": round(statistics.median(r["cpu_s"] for r in rows), 1), "error": last["error"]}


def verdict(measured: dict) -> tuple[bool, str | None]:
    """In the evaluation set, or why not."""
    if measured["error"]:
        return False, f"its own settings fail: {measured['error']} at iteration {measured['iterations']}"
    if not measured["converged"]:
        return False, f"its own settings do not converge: not converged in {measured['iterations']}"
    if measured["wall_s"] > BUDGET_S:
        return False, f"{measured['wall_s']} s a run, over the {BUDGET_S:.0f} s budget"
    return True, None


def machine() -> dict:
    """nproc, CPU model, OpenFOAM version (from a utility's banner)."""
    cpu = re.search(r"model name\s*:\s*(.*)", Path("/proc/cpuinfo").read_text())
    env = dict(os.environ, WM_PROJECT_DIR=os.environ.get("WM_PROJECT_DIR", "/usr/share/openfoam"))
    banner = subprocess.run(["simpleFoam", "-help"], capture_output=True, text=True, env=env, check=False)
    version = re.search(r"OpenFOAM-\s*\((\d+)\)", banner.stdout + banner.stderr)
    patch = re.search(r"patch=(\d+)", banner.stdout + banner.stderr)
    return {"nproc": os.cpu_count(), "cpu": cpu.group(1).strip() if cpu else None,
            "openfoam": f"v{version.group(1) if version else '?'} (patch {patch.group(1) if patch else '?'})",
            "load": "shared: a training run and another engineer's jobs ran beside these measurements"}


def main() -> None:
    runs: dict[str, list[dict]] = {}
    for line in (HERE / "measurements.jsonl").read_text().splitlines():
        row = json.loads(line)
        runs.setdefault(row["case"], []).append(row)
    cases = []
    for name, (source, geometry, shared) in CASES.items():
        measured = own(runs[name]) if name in runs else None
        ok, why = verdict(measured) if measured else (False, "not measured")
        if shared:
            ok, why = False, "; ".join(filter(None, [why, f"its geometry is a training base's: {shared}"]))
        cases.append({"name": name, "source": source, "geometry": geometry, "shares_geometry_with": shared,
                      **(measured or {}), "in_evaluation": ok, "why_out": why, "note": NOTES.get(name)})
    out = {"format": 1, "date": time.strftime("%Y-%m-%d"), "machine": machine(), "budget_s": BUDGET_S,
           "cases": cases, "not_built": NOT_BUILT}
    (HERE / "heldout.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
