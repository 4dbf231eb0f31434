"""What the answer monitor of ``solve --settle`` costs: the same iterations of a case with and without it.

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python benchmarks/bench_settle_cost.py \
        --out benchmarks/results/settle-cost-DATE --pairs 5

Each pair is two runs of the same case through ``solve_case`` to the same iteration count (a criterion it
never meets: its whole budget, its own endTime): the plain run (``settle=None``) and the monitored one with
a tolerance it cannot reach (1e-12: the monitor samples and judges all the way, and never stops the run), in
alternating order. Per run: simpleFoam's own CPU seconds (its ExecutionTime: on a noisy, shared machine the
solver's own figure for the same iterations, which the binary writes every 25 iterations add to) and the
monitor's own CPU seconds (its process's time in its polls, beside the solver). Reported per case: the medians
of the monitor's CPU seconds, of (monitored solver CPU / plain solver CPU - 1) and of (monitor CPU / plain
solver CPU), and the sum of the last two: the cost on top of the plain run. Cases: pitzDaily (the tutorial,
12,225 cells, no function object read), heldout-v2's squareTubeRow with a user's forces, a probe and an
outlet average (function objects every iteration) and the simpleCar tutorial (12,940 cells; its binned
force coefficients are 496 values every iteration; its runTimeControl, an average of Cd, ends it at iteration
208 whatever the criterion). Writes OUT/settle_cost.jsonl (every run) and OUT/settle_cost.md (machine,
date, medians);
``--table-only`` writes the table again from OUT/settle_cost.jsonl.
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import json
import os
import platform
import shutil
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")
NEVER = "1e-12"
FUNCTION_OBJECTS = """
functions
{
    forces { type forces; libs (forces); writeControl timeStep; writeInterval 1; log false; patches (walls);
             rho rhoInf; rhoInf 1; CofR (0 0 0); }
    outletP { type surfaceFieldValue; libs (fieldFunctionObjects); writeControl timeStep;
              writeInterval 1; log false; writeFields false; regionType patch; name outlet;
              operation areaAverage; fields (p); }
    probes { type probes; libs (sampling); writeControl timeStep; writeInterval 1; fields (p U);
             probeLocations ((3 0.5 0.05)); }
}
"""


def cases(root: Path) -> dict[str, Path]:
    """The benchmark's cases, built under ``root``."""
    built = {}
    pitz = root / "pitzDaily"
    if not pitz.exists():
        shutil.copytree(TUTORIALS / "pitzDaily", pitz)
    built["pitzDaily"] = pitz
    row = root / "squareTubeRowFO"
    if not row.exists():
        spec = importlib.util.spec_from_file_location(
            "heldout_v2_cases", ROOT / "experiments" / "controller" / "heldout-v2" / "cases.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        module.CASES["squareTubeRow"](row)
        control = row / "system" / "controlDict"
        control.write_text(control.read_text() + FUNCTION_OBJECTS)
    built["squareTubeRowFO"] = row
    car = root / "simpleCar"
    if not car.exists():
        sys.path.insert(0, str(ROOT / "experiments" / "controller" / "heldout-v1"))
        from prepare import simpleCar  # the tutorial's Allrun (heldout-v1's builder)

        simpleCar(car)
    built["simpleCar"] = car
    return built


def one_run(case: Path, out: Path, monitored: bool) -> dict:
    from jaxsimrl.apps.foam.solve import solve_case

    shutil.rmtree(out, ignore_errors=True)
    report = solve_case(case, out, residual=NEVER, settle=1e-12 if monitored else None)
    result = report.data["result"]
    answer = report.data.get("answer") or {}
    return {"iterations": result["iterations"], "solver_cpu_s": result["solver_cpu_time_s"],
            "monitor_cpu_s": answer.get("monitor_cpu_s", 0.0), "monitored": monitored}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--pairs", type=int, default=5)
    parser.add_argument("--only", nargs="+", help="these cases alone")
    parser.add_argument("--table-only", action="store_true")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.table_only:
        rows = [json.loads(line) for line in (args.out / "settle_cost.jsonl").read_text().splitlines()]
    else:
        rows = measure(args.pairs, args.only)
        with open(args.out / "settle_cost.jsonl", "w") as file:
            file.writelines(json.dumps(row) + "\n" for row in rows)
    write_table(args.out, rows, args.pairs)


def measure(pairs: int, only: list[str] | None = None) -> list[dict]:
    work = Path(os.environ.get("TMPDIR", "/tmp")) / "bench_settle_cost"
    rows = []
    for name, case in cases(work).items():
        if only and name not in only:
            continue
        for pair in range(pairs):
            order = (False, True) if pair % 2 == 0 else (True, False)
            for monitored in order:
                row = {"case": name, "pair": pair, **one_run(case, work / "out", monitored)}
                rows.append(row)
                print(json.dumps(row), flush=True)
    return rows


def write_table(out: Path, rows: list[dict], count: int) -> None:
    lengths = ", ".join(f"{name} {iterations}" for name, iterations in
                        {row["case"]: row["iterations"] for row in rows}.items())
    lines = [f"# The answer monitor's cost ({datetime.date.today()}, {platform.node()}, {_cpu()}, "
             f"{os.cpu_count()} cores; {count} alternated pairs; iterations: {lengths})",
             "", "| case | solver CPU plain (median s) | monitor CPU (median s) | solver's extra CPU "
             "| monitor's CPU | total |", "|---|---|---|---|---|---|"]
    for name in dict.fromkeys(row["case"] for row in rows):
        pairs = [[r for r in rows if r["case"] == name and r["pair"] == p] for p in range(count)]
        plain = [next(r for r in pair if not r["monitored"]) for pair in pairs]
        watched = [next(r for r in pair if r["monitored"]) for pair in pairs]
        extra = statistics.median(w["solver_cpu_s"] / p["solver_cpu_s"] - 1 for p, w in zip(plain, watched,
                                                                                                strict=True))
        monitor = statistics.median(w["monitor_cpu_s"] / p["solver_cpu_s"] for p, w in zip(plain, watched,
                                                                                               strict=True))
        lines.append(f"| {name} | {statistics.median(p['solver_cpu_s'] for p in plain):.1f} | "
                     f"{statistics.median(w['monitor_cpu_s'] for w in watched):.2f} | "
                     f"{100 * extra:+.1f} % | {100 * monitor:.1f} % | {100 * (extra + monitor):.1f} % |")
    (out / "settle_cost.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


if __name__ == "__main__":
    main()
