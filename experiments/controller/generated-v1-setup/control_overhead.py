# SPDX-License-Identifier: GPL-3.0-or-later
"""What does driving a run cost by itself? Each case run by plain simpleFoam at its own settings
(validate.py's own run) and through ``solve`` by a rule that keeps its own factors but steps every 25
iterations as the learned controller does (a controlled run: the pause at every step, the state function
objects, the convergence check; solve's own rule runs plain and would not show them), alternated round
after round so that the machine's load falls alike on both. A learned controller must save this much
before it gains anything in what a user pays.

    .venv/bin/python experiments/controller/generated-v1-setup/control_overhead.py runs/generated-val \\
        --rounds 2 --out experiments/controller/generated-v1-setup/control-overhead.jsonl
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
from pathlib import Path

from validate import solved

from jaxsimrl.apps.foam.solve import rules, runner
from jaxsimrl.apps.foam.solve.own import run_own

# The own rule stepped at the learned controller's interval (train-config-v3.json's): solve runs its
# default rule plain, so for this measurement only the runner is told its default is another name.
rules.INTERVALS["own"] = 25
runner.DEFAULT_RULE = "(none: own stepped)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("cases", type=Path)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    cases = sorted(p for p in args.cases.iterdir() if (p / "system" / "controlDict").is_file())
    ratios: dict[str, list[tuple[float, float]]] = {}
    with tempfile.TemporaryDirectory(prefix="control-overhead-") as scratch:
        for round_ in range(args.rounds):
            for case in cases:
                own = run_own(case, Path(scratch) / f"{round_}-own-{case.name}", "own", 3600.0)
                driven = solved(case, Path(scratch) / f"{round_}-driven-{case.name}", rule="own")
                row = {"case": case.name, "round": round_, "own_iterations": own.iterations,
                       "own_cpu_s": own.cpu_time_s, "driven_iterations": driven["iterations"],
                       "driven_cpu_s": driven["cpu_s"]}
                with args.out.open("a") as handle:
                    handle.write(json.dumps(row) + "\n")
                ratios.setdefault(case.name, []).append((driven["iterations"] / own.iterations,
                                                          driven["cpu_s"] / own.cpu_time_s))
    for name, pairs in ratios.items():
        print(f"{name:>14}: driven/own iterations {statistics.median(p[0] for p in pairs):.2f}x, "
              f"CPU {statistics.median(p[1] for p in pairs):.2f}x")
    print(f"median over cases: iterations "
          f"{statistics.median(statistics.median(p[0] for p in v) for v in ratios.values()):.2f}x, CPU "
          f"{statistics.median(statistics.median(p[1] for p in v) for v in ratios.values()):.2f}x")


if __name__ == "__main__":
    main()
