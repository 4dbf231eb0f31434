"""Wall time of ``jaxsimrl solve CASE`` (the whole command, as a user waits for it) against ``simpleFoam``
alone on the same prepared case (its mesh made), on OpenFOAM's simpleFoam tutorials.

    .venv/bin/python benchmarks/bench_solve_wall.py pitzDaily T3A --repeats 3 --out /tmp/wall

Each repeat runs the two one after the other, alternating which goes first, each on a fresh copy, nothing
else of this script running beside them; the ratio is taken pair by pair and the median of the pairs is
quoted (a machine whose speed drifts moves both runs of a pair). Iterations are exact: the plain run's
last ``Time =`` and solve.json's. Writes OUT/wall.json (machine, date, every run, the medians).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

TUTORIALS = Path("/usr/share/doc/openfoam-examples/examples/incompressible/simpleFoam")
JAXSIMRL = Path(sys.executable).with_name("jaxsimrl")


def prepare(name: str, root: Path) -> Path:
    """A copy of the tutorial with its mesh (blockMesh where it has no polyMesh), as a user runs it."""
    case = root / "prepared" / name
    shutil.rmtree(case, ignore_errors=True)
    shutil.copytree(TUTORIALS / name, case)
    if not (case / "constant" / "polyMesh" / "faces").exists() and \
            not (case / "constant" / "polyMesh" / "faces.gz").exists():
        subprocess.run(["blockMesh", "-case", str(case)], check=True, capture_output=True)
    return case


def plain(case: Path, dest: Path) -> tuple[float, int]:
    """simpleFoam alone on a fresh copy: (wall s, iterations)."""
    shutil.rmtree(dest, ignore_errors=True)
    shutil.copytree(case, dest)
    started = time.monotonic()
    done = subprocess.run(["simpleFoam", "-case", str(dest)], capture_output=True, text=True)
    wall = time.monotonic() - started
    times = re.findall(r"^Time = (\S+)$", done.stdout, re.MULTILINE)
    return wall, int(float(times[-1])) if times else 0


def solve(case: Path, dest: Path, controller: str) -> tuple[float, int, dict]:
    """``jaxsimrl solve`` as a user types it: (wall s, iterations, solve.json's result)."""
    shutil.rmtree(dest, ignore_errors=True)
    started = time.monotonic()
    subprocess.run([str(JAXSIMRL), "solve", str(case), "--out", str(dest), "--controller", controller],
                   capture_output=True, text=True)
    wall = time.monotonic() - started
    result = json.loads((dest / "solve.json").read_text())["result"]
    return wall, int(result["iterations"]), result


def bench(name: str, root: Path, repeats: int, controller: str) -> dict:
    case = prepare(name, root)
    runs = []
    for repeat in range(repeats):
        order = ("plain", "solve") if repeat % 2 == 0 else ("solve", "plain")
        row: dict = {"first": order[0]}
        for which in order:
            if which == "plain":
                row["plain_wall_s"], row["plain_iterations"] = plain(case, root / "runs" / f"{name}.plain")
            else:
                wall, iterations, result = solve(case, root / "runs" / f"{name}.solved", controller)
                row.update(solve_wall_s=wall, solve_iterations=iterations,
                           phases=result.get("phases", {}), solver_busy_s=result["solver_busy_s"])
        row["ratio_wall"] = row["solve_wall_s"] / row["plain_wall_s"]
        runs.append(row)
        print(f"{name} #{repeat}: plain {row['plain_wall_s']:.2f} s ({row['plain_iterations']} it), solve "
              f"{row['solve_wall_s']:.2f} s ({row['solve_iterations']} it), ratio {row['ratio_wall']:.3f}",
              flush=True)
    iterations = runs[0]["solve_iterations"] / runs[0]["plain_iterations"]
    return {"case": name, "controller": controller, "runs": runs,
            "ratio_iterations": round(iterations, 3),
            "median_plain_wall_s": round(statistics.median(r["plain_wall_s"] for r in runs), 2),
            "median_solve_wall_s": round(statistics.median(r["solve_wall_s"] for r in runs), 2),
            "median_ratio_wall": round(statistics.median(r["ratio_wall"] for r in runs), 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="+")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--controller", default="learned")
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    rows = [bench(name, args.out.resolve(), args.repeats, args.controller) for name in args.names]
    load = os.getloadavg()
    data = {"date_utc": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
            "machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores",
            "cpu": _cpu(), "load_average_after": load, "rows": rows}
    (args.out / "wall.json").write_text(json.dumps(data, indent=1))
    for row in rows:
        print(f"{row['case']}: iterations {row['ratio_iterations']}, wall median {row['median_ratio_wall']} "
              f"(plain {row['median_plain_wall_s']} s, solve {row['median_solve_wall_s']} s)")


def _cpu() -> str:
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.machine()


if __name__ == "__main__":
    main()
