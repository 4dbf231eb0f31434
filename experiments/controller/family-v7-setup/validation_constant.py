"""The training family's constant (FAMILY_CONSTANT) and the own settings on the validation variants, beside
validate.py's ratios: what the learned controller's checkpoints are chosen against.

    .venv/bin/python experiments/controller/family-v7-setup/validation_constant.py \\
        runs/family-val-full OUT.json
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

from atomicfile import atomic_write_text
from jaxsimrl.apps.foam.solve.own import run_own
from jaxsimrl.apps.foam.solve.settings import FAMILY_CONSTANT, read_case_settings


def main() -> None:
    cases = sorted(p for p in Path(sys.argv[1]).iterdir() if (p / "system" / "controlDict").is_file())
    rows = []
    with tempfile.TemporaryDirectory(prefix="validation-constant-") as scratch:
        for case in cases:
            constant = list(FAMILY_CONSTANT[read_case_settings(case).variant])
            own = run_own(case, Path(scratch) / f"own-{case.name}", "own", 3600.0)
            fixed = run_own(case, Path(scratch) / f"constant-{case.name}", "constant", 3600.0,
                            factors=constant)
            rows.append({"case": case.name, "own": own.iterations, "constant": constant,
                         "constant_iterations": fixed.iterations, "constant_converged": fixed.converged,
                         "ratio": round(fixed.iterations / own.iterations, 3)})
            print(rows[-1], flush=True)
    atomic_write_text(sys.argv[2], json.dumps(rows, indent=1) + "\n")


if __name__ == "__main__":
    main()
