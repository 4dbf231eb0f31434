# SPDX-License-Identifier: GPL-3.0-or-later
"""Write heldout.json, the fixed heldout-v2 list: each case's description (cases.py), its own settings'
measurements (measurements.jsonl, from heldout-v1's measure.py: medians of its runs) and whether it is in
the evaluation set; the date, the machine and the OpenFOAM version.

    .venv/bin/python experiments/controller/heldout-v2/tabulate.py

A case is in the set when its own settings converge within its own endTime in every run, with the same
iteration count, its median solver CPU time (OpenFOAM's ExecutionTime) is under BUDGET_S, and its kind is
one reserved_kinds.json reserves.
"""

from __future__ import annotations

import json
import re
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(1, str(HERE.parent / "heldout-v1"))

from cases import DESCRIPTIONS  # noqa: E402
from table import machine, own  # noqa: E402

BUDGET_S = 180.0

#: What the runs showed beyond the verdict (from their logs, read while they ran).
NOTES: dict[str, str] = {
    "circularCylinder": "stopped by hand at iteration 810: Uy's residual flat at 8e-2 from iteration ~300 "
                        "(the wake sheds); 67 ms of CPU an iteration, its 4000 would also pass 180 s",
    "annularDuct": "stopped by hand at iteration 716: every field under 1e-5 but Uz, the wedge's swirl "
                   "component (zero: no swirl), whose normalised residual stays at 1.0e-2 from "
                   "iteration ~300",
    "slotJetFine": "stopped by hand at iteration 1485 (103 s of CPU): p between 3e-3 and 1e-2 from "
                   "iteration ~400; its 3000 iterations would also pass 180 s of CPU",
    "swirlAnnularDuct": "stopped by hand at iteration 1095 (94 s of CPU): residuals frozen from iteration "
                        "~700 at Uy 1.17e-4, p 1.24e-4 (1e-4 asked)",
    "annex20Room": "past the 300 s wall-clock timeout at iteration 3068 (131 s of CPU), p 4e-3; its 5000 "
                   "iterations would take ~215 s of CPU, over the budget",
    "tubeBankStaggered": "past the 300 s wall-clock timeout at iteration 987 (82 s of CPU): residuals 1e-2 "
                         "to 9e-2, the wakes shed",
    "annex20Mid": "past the 600 s wall-clock timeout at iteration 2737 (122 s of CPU), p 1.3e-2",
    "annex20FastSIMPLE": "a first run was stopped by hand at iteration 1425 (63 s of CPU, p 3e-3) to free "
                         "the machine, leaving no row; measured again to its end",
    "tubeBankInline": "Uy flat at 4.9e-2 from iteration ~500: the wakes shed",
    "squareCylinder": "p at 6e-2 at iteration 2100: the wake sheds",
    "officeRoom": "U residuals flat at ~3e-2, p at ~1e-1 from iteration ~100",
    "slotJetConfined": "p ~1e-3 at iteration 1100 (1e-5 asked)",
    "ellipseCylinder": "stopped by hand at iteration 1701: p flat at 1.7e-1 from iteration ~1000",
    "tubeBankDense": "stopped by hand at iteration 1747: residuals 1e-2 to 6e-2 from iteration ~1000, the "
                     "wakes shed",
    "porousTwoBlocks": "stopped by hand at iteration 2628: residuals frozen from iteration ~1400 at epsilon "
                       "1.06e-4 (1e-4 asked), the rest under 7e-5",
    "squareTubeStaggered": "its first run passed the 600 s wall-clock timeout at iteration 1509 (103 s of "
                           "CPU, the machine loaded ~5x); measured again with a 1500 s timeout",
}

#: The load beside the measurements (uptime and ps, read while they ran).
LOAD = ("shared 2-core machine, heavily loaded: other engineers' jobs (a JAX Lorenz training, simpleFoam "
        "trajectories, a benchmark) and up to 7 of these measurement streams at once (nice 5); load average "
        "4 to 16; wall seconds 2-5x the CPU seconds")


def verdict(measured: dict, kind: str, reserved: set[str]) -> tuple[bool, str | None]:
    """In the evaluation set, or why not."""
    if kind not in reserved:
        return False, f"its kind {kind} is not reserved"
    if measured["error"]:
        return False, f"its own settings fail: {measured['error']} at iteration {measured['iterations']}"
    if not measured["converged"]:
        code = measured["exit_code"]
        how = ("run past measure.py's wall-clock timeout" if code is None
               else "run stopped by hand" if code < 0 else "not converged within its endTime")
        return False, f"its own settings do not converge: {how}, at iteration {measured['iterations']}"
    if len(set(measured["iterations_runs"])) > 1:
        return False, f"its runs differ: {measured['iterations_runs']} iterations"
    if measured["cpu_s"] > BUDGET_S:
        return False, f"{measured['cpu_s']} s of solver CPU a run, over the {BUDGET_S:.0f} s budget"
    return True, None


def cpu_family() -> str:
    """The CPU's family and model numbers (lscpu's "CPU family" and "Model")."""
    info = Path("/proc/cpuinfo").read_text()
    family, model = (re.search(rf"{key}\s*:\s*(\d+)", info) for key in ("cpu family", "model"))
    return f"family {family.group(1) if family else '?'}, model {model.group(1) if model else '?'}"


def main(here: Path = HERE, descriptions: dict = DESCRIPTIONS, notes: dict[str, str] = NOTES,
         load: str = LOAD) -> None:
    """heldout.json of the set in ``here`` (heldout-v3's tabulate.py passes its own; the kinds and the rule
    are v2's)."""
    reserved = {r["kind"] for r in json.loads((HERE / "reserved_kinds.json").read_text())["reserved"]}
    rows = [json.loads(line) for line in (here / "measurements.jsonl").read_text().splitlines()]
    cases = []
    for name, (source, kind, geometry) in descriptions.items():
        mine = [r for r in rows if r["case"] == name]
        # a run cut by measure.py's wall-clock timeout (exit_code null) says nothing of the case on a loaded
        # machine: it is kept in measurements.jsonl, but not counted when the case has runs that ended
        ended = [r for r in mine if r["exit_code"] is not None] or mine
        measured = ({**own(ended), "cpu_s_runs": [r["cpu_s"] for r in ended],
                     "exit_code": ended[-1]["exit_code"]} if ended else None)
        if measured:
            measured["model"] = measured.pop("turbulence_model") or "laminar"
        ok, why = verdict(measured, kind, reserved) if measured else (False, "not measured")
        cases.append({"name": name, "source": source, "kind": kind, "geometry": geometry, **(measured or {}),
                      "in_evaluation": ok, "why_out": why, "note": notes.get(name)})
    dates = sorted(row["date"] for row in rows)
    out = {"format": 1, "date": time.strftime("%Y-%m-%d"),
           "measured": [dates[0], dates[-1]] if dates else None,
           "machine": {**machine(), "cpu_family": cpu_family(), "load": load}, "budget_cpu_s": BUDGET_S,
           "reserved_kinds": sorted(reserved), "cases": cases}
    (here / "heldout.json").write_text(json.dumps(out, indent=1) + "\n")
    print("| case | kind | in | algorithm | model | cells | own iterations (runs) | solver CPU s | why out |")
    print("|---|---|---|---|---|---|---|---|---|")
    for case in sorted(cases, key=lambda c: (not c["in_evaluation"], c["kind"], c["name"])):
        runs_text = ", ".join(map(str, case.get("iterations_runs", [])))
        print(f"| {case['name']} | {case['kind']} | {'**in**' if case['in_evaluation'] else 'out'} | "
              f"{case.get('algorithm', '')} | {case.get('model', '')} | {case.get('cells', '')} | "
              f"{runs_text} | {case.get('cpu_s', '')} | {(case['why_out'] or '').split(': ', 1)[-1]} |")

if __name__ == "__main__":
    main()
