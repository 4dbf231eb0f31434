"""Does a tutorial's converged answer depend on its relaxation factors? The case's own run, then the same
run carried on from its converged fields at other constant factors until it converges again; the
relative L2 distance of the fields (``--fields``) between the two, and from a ``jaxsimrl solve`` result.

    .venv/bin/python benchmarks/bench_relaxation_dependence.py airFoil2D --factors 0.831 0.356 0.831 \
        --solved /work/bench-rules/rule/airFoil2D.solved --out benchmarks/results/rules-2026-12-03

If the carried-on run lands as far from the own run as the solve result does, and next to the solve
result, the difference ``solve --compare`` flags is the discrete problem's dependence on relaxation
(simpleFoam's face fluxes depend on the relaxed momentum diagonal), not an unconverged controlled run.
Writes OUT/relaxation_dependence_CASE.json.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from foam_bridge._fields import final_field, relative_l2
from jaxsimrl.apps.foam.solve.own import run_own

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")
#: The fields compared unless --fields names others.
FIELDS = ("p", "U")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("case", help="a tutorial of incompressible/simpleFoam")
    parser.add_argument("--factors", type=float, nargs=3, required=True, metavar="F",
                        help="alpha_u alpha_p turbulence of the carried-on run")
    parser.add_argument("--solved", type=Path, help="a solve --out of the same tutorial")
    parser.add_argument("--fields", nargs="+", default=list(FIELDS), metavar="NAME")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        own = run_own(TUTORIALS / args.case, Path(scratch) / "own", "own", 3600.0)
        carried = run_own(Path(own.case), Path(scratch) / "carried", "carried", 3600.0, args.factors,
                          start_time=own.iterations)
        runs = {"own": Path(own.case), "carried_on": Path(carried.case)}
        if args.solved is not None:
            runs["solve"] = args.solved.resolve()
        fields = {name: {f: final_field(path, f) for f in args.fields} for name, path in runs.items()}
        pairs = [("carried_on", "own"), ("solve", "own"), ("solve", "carried_on")]
        distances = {f"{a} vs {b}": {f: relative_l2(fields[a][f][1], fields[b][f][1]) for f in args.fields}
                     for a, b in pairs if a in fields and b in fields}
    report = {"case": args.case, "factors": args.factors, "own_iterations": own.iterations,
              "carried_on_iterations": carried.iterations, "carried_on_converged": carried.converged,
              "solve": None if args.solved is None else str(args.solved), "relative_l2": distances}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"relaxation_dependence_{args.case}.json").write_text(json.dumps(report, indent=1) + "\n")
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
