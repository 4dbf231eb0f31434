# SPDX-License-Identifier: GPL-3.0-or-later
"""Build the heldout-v2 cases (issue 46): each a plain simpleFoam case, meshed, ready to run.

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/controller/heldout-v2/prepare.py \
        [runs/heldout-v2] [--only NAME ...] [--evaluation]

The builders are in cases.py (one docstring per case: geometry, reserved kind, Reynolds number, model,
algorithm, own factors and criterion, why). Deterministic: the same files every time.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from cases import CASES, TUTORIALS


def selected(only: list[str] | None, evaluation: bool, cases: dict, table_path: Path) -> list[str]:
    """The cases to build: ``only`` (else all), restricted to heldout.json's evaluation set if asked."""
    names = list(only or cases)
    if not evaluation:
        return names
    table = json.loads(table_path.read_text())
    chosen = {case["name"] for case in table["cases"] if case["in_evaluation"]}
    return [name for name in names if name in chosen]


def main(argv: list[str] | None = None, cases: dict | None = None, here: Path = Path(__file__).parent,
         description: str = __doc__) -> None:
    """Build ``cases`` (default heldout-v2's) of the set in ``here`` (heldout-v3's prepare.py reuses this)."""
    cases = CASES if cases is None else cases
    cli = argparse.ArgumentParser(description=description.splitlines()[0])
    cli.add_argument("--evaluation", action="store_true", help="only the evaluation set (heldout.json)")
    cli.add_argument("--only", nargs="+", choices=sorted(cases), metavar="NAME", help="only these cases")
    cli.add_argument("out", type=Path, nargs="?", default=Path("runs") / here.name, help="where to build")
    args = cli.parse_args(argv)
    if not TUTORIALS.is_dir():
        raise SystemExit(f"no OpenFOAM tutorials at {TUTORIALS}")
    for name in selected(args.only, args.evaluation, cases, here / "heldout.json"):
        print(f"building {name}", flush=True)
        cases[name](args.out / name)


if __name__ == "__main__":
    main()
