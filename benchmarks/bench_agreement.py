"""How far two converged runs of pitzDaily are apart, and how that scales with the criterion: the
measurements behind the tolerance rule of jaxsimrl.apps.foam.solve.agreement.

    .venv/bin/python benchmarks/bench_agreement.py --out /tmp/agreement

pitzDaily (OpenFOAM's tutorial, its mesh and settings) with function objects a user might add (probes,
forces on one wall and on both, fieldMinMax, the inlet's mean pressure, the outlet's flow rate, wall shear
stress), at its own criterion (p 1e-2, U and k/epsilon 1e-3: r = 1e-2, the loosest) and 10x tighter:

- ``solve --compare --compare-constant 0.7 0.5 0.7``: the controller, the case's own settings and a slow
  constant (3-4x the iterations), all converged to the same criterion;
- own runs converged to a 3x and a 10x looser criterion (stopped early);
- a reference: the own settings, the criterion 100x tighter, 2000 iterations (it does not meet it; the
  controller and the own run agree there to 4e-5).

Writes OUT/agreement.json and prints: each run's fields' relative L2 distance to the reference, and the
difference between pairs of runs (fields, function objects; the latter also without forcesWalls, whose
pressure moment is a small difference of the two walls' large ones), in units of r. ``--print-only``
prints from an OUT/agreement.json already written.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
from pathlib import Path

from foam_bridge._export import latest_time
from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.apps.foam.solve.agreement import field_difference, function_object_differences
from jaxsimrl.apps.foam.solve.controller import DEFAULT_CONTROLLER
from jaxsimrl.apps.foam.solve.own import OwnProcess

TUTORIAL = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam/pitzDaily")
FIELDS = ("U", "p", "k", "epsilon")
LOOSEST = 1e-2  # the tutorial's p threshold
FUNCTIONS = """
    #includeFunc fieldMinMax(U,p)
    #includeFunc patchAverage(name=inlet,p)
    #includeFunc flowRatePatch(name=outlet)
    #includeFunc wallShearStress
    probes { type probes; libs (sampling); fields (p U);
             probeLocations ((0.01 0 0) (0.1 0.01 0) (0.2 -0.01 0) (0.28 0 0)); }
    forces { type forces; libs (forces); patches (lowerWall); rho rhoInf; rhoInf 1; CofR (0 0 0); }
    forcesWalls { type forces; libs (forces); patches (lowerWall upperWall); rho rhoInf; rhoInf 1;
                  CofR (0 0 0); }
"""


def prepare(root: Path, name: str, scale: float, end_time: int | None = None) -> Path:
    """pitzDaily with FUNCTIONS and its residualControl thresholds x ``scale`` (``end_time``: its budget)."""
    case = root / name
    shutil.rmtree(case, ignore_errors=True)
    shutil.copytree(TUTORIAL, case)
    control = case / "system" / "controlDict"
    text = control.read_text().replace("#includeFunc streamlines\n", "#includeFunc streamlines\n" + FUNCTIONS)
    if end_time is not None:
        text = re.sub(r"\nendTime\s+\d+;", f"\nendTime {end_time};", text)
    control.write_text(text)
    solution = case / "system" / "fvSolution"
    text = solution.read_text()
    block = re.search(r"residualControl\s*\{[^}]*\}", text).group(0)
    scaled = re.sub(r"(\s)([0-9.]+e-?[0-9]+);", lambda m: f"{m.group(1)}{float(m.group(2)) * scale:g};",
                    block)
    solution.write_text(text.replace(block, scaled))
    return case


def own_run(case: Path, dest: Path) -> Path:
    """The case with its own settings (spawned: this process has JAX loaded), its directory."""
    shutil.rmtree(dest, ignore_errors=True)
    process = OwnProcess(case, dest, "own", 3600.0, None, False)
    try:
        result = process.result(3600.0)
    finally:
        process.stop()
    print(f"{dest.name}: {result.iterations} iterations, converged {result.converged}", flush=True)
    return dest


def measure(root: Path) -> dict:
    runs: dict[str, Path] = {}
    for label, scale in (("", 1.0), ("tight", 0.1)):
        case = prepare(root, f"pitzDaily{label}", scale)
        out = root / f"pitzDaily{label}.solved"
        shutil.rmtree(out, ignore_errors=True)
        solve_case(case, out, policy=DEFAULT_CONTROLLER, compare=True, compare_constant=(0.7, 0.5, 0.7))
        suffix = f" {label}" if label else ""
        runs |= {f"controller{suffix}": out, f"own{suffix}": out / "compare" / "own",
                 f"constant{suffix}": out / "compare" / "constant"}
    for factor in (3, 10):
        loose = prepare(root, f"loose{factor}", factor)
        runs[f"own {factor}x looser"] = own_run(loose, root / f"loose{factor}.run")
    reference = own_run(prepare(root, "reference", 0.01, end_time=2000), root / "reference.run")
    pairs = [("controller", "own"), ("controller", "constant"), ("constant", "own"),
             ("controller tight", "own tight"), ("controller tight", "constant tight"),
             ("constant tight", "own tight"), ("own 3x looser", "controller"),
             ("own 10x looser", "controller")]
    return {"r": LOOSEST,
            "iterations": {name: int(latest_time(case).name) for name, case in runs.items()},
            "to_reference": {name: _fields(case, reference) for name, case in runs.items()},
            "pairs": {f"{a} vs {b}": {"fields": _fields(runs[a], runs[b]),
                                      "function_objects": function_object_differences(runs[a], runs[b])[0]}
                      for a, b in pairs}}


def _fields(case: Path, reference: Path) -> dict[str, float | None]:
    return {name: field_difference(case, reference, name)[0] for name in FIELDS}


def _worst(values: dict[str, float | None], label: str) -> str:
    """The largest value, in units of the criterion's loosest threshold (10x tighter for "tight" runs)."""
    name, value = max(((k, v) for k, v in values.items() if v is not None), key=lambda item: item[1])
    r = LOOSEST * (0.1 if "tight" in label else 1.0)
    return f"{value:.1e} = {value / r:4.1f} r ({name})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--print-only", action="store_true", help="print OUT/agreement.json, run nothing")
    args = parser.parse_args()
    if args.print_only:
        data = json.loads((args.out / "agreement.json").read_text())
    else:
        args.out.mkdir(parents=True, exist_ok=True)
        data = measure(args.out)
        (args.out / "agreement.json").write_text(json.dumps(data, indent=1) + "\n")
    for name, fields in data["to_reference"].items():
        print(f"{name:18s} {data['iterations'][name]:5d} iterations, fields to the reference "
              f"{_worst(fields, name)}")
    for pair, values in data["pairs"].items():
        objects = values["function_objects"]
        one_wall = {name: value for name, value in objects.items() if not name.startswith("forcesWalls/")}
        print(f"{pair:36s} fields {_worst(values['fields'], pair)}, function objects "
              f"{_worst(objects, pair)}, without forcesWalls {_worst(one_wall, pair)}")


if __name__ == "__main__":
    main()
