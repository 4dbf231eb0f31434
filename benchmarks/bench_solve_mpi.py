"""solve --np 2 against the case's own settings, serial and -np 2 (benchmarks/results/mpi-2026-12-04/).

    python benchmarks/bench_solve_mpi.py OUT_JSON WORK CASE...

Per case: ``jaxsimrl solve CASE --np 2 --compare`` (its comparison: the case's own settings on 2 ranks,
after the controlled run on a 2-core machine), and the case's own settings serial
(jaxsimrl.apps.foam.solve.own). Records iterations and walls of the three runs, and the agreement of the --np
2 result with the serial run's fields (jaxsimrl.apps.foam.solve.agreement, --compare's tolerance).
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path
from typing import Any


def measure(case: Path, work: Path) -> dict[str, Any]:
    """One case's numbers (see the module docstring)."""
    from jaxsimrl.apps.foam.solve.agreement import compare_results
    from jaxsimrl.apps.foam.solve.own import run_own

    out = work / f"{case.name}.np2"
    started = time.monotonic()
    subprocess.run([sys.executable, "-m", "jaxsimrl", "solve", str(case), "--out", str(out), "--np", "2",
                    "--compare", "--quiet", "--controller", "learned"], check=False)
    solve_wall = time.monotonic() - started
    report = json.loads((out / "solve.json").read_text())
    serial = run_own(case, work / f"{case.name}.own-serial", "own", 3600.0)
    criterion = report["settings"]["criterion"]
    fields = list(criterion)
    agreement = compare_results(out, Path(serial.case), fields, criterion,
                                (report["result"]["converged"], serial.converged), "serial")
    own2 = report["compare"]["own"]
    return {"case": case.name, "solve_np2": {"iterations": report["result"]["iterations"],
                                             "converged": report["result"]["converged"],
                                             "wall_s": round(solve_wall, 1),
                                             "controlled_run_s": round(report["result"]["phases"]
                                                                       ["controlled_run_s"], 1)},
            "own_np2": {"iterations": own2.get("iterations"), "converged": own2.get("converged"),
                        "wall_s": own2.get("wall_time_s")},
            "own_serial": {"iterations": serial.iterations, "converged": serial.converged,
                           "wall_s": round(serial.wall_time_s, 1)},
            "np2_vs_own_np2": report["compare"]["own"].get("agreement"),
            "np2_vs_own_serial": agreement}


def main(argv: list[str]) -> int:
    out, work, cases = Path(argv[0]), Path(argv[1]), [Path(a) for a in argv[2:]]
    work.mkdir(parents=True, exist_ok=True)
    rows = []
    for case in cases:
        rows.append(measure(case, work))
        out.write_text(json.dumps({"machine": f"{platform.node()} {os.cpu_count()} cores (shared)",
                                   "date": time.strftime("%Y-%m-%d"), "cases": rows}, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
