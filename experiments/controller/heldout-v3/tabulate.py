# SPDX-License-Identifier: GPL-3.0-or-later
"""Write heldout.json, the fixed heldout-v3 list, by heldout-v2's rule (its tabulate.py): a case is in the
evaluation set when its own settings converge within its own endTime in both runs, with the same iteration
count, its median solver CPU is under 180 s here, and its kind is one heldout-v2 reserves.

    .venv/bin/python experiments/controller/heldout-v3/tabulate.py
"""

from __future__ import annotations

from pathlib import Path

from cases import DESCRIPTIONS, v2_module

HERE = Path(__file__).resolve().parent

#: What the runs showed beyond the verdict (from their logs).
NOTES: dict[str, str] = {}

LOAD = ("shared 2-core machine: a train-foam run (pool 2) and a validation stream beside the measurements "
        "(one measurement at a time, nice 5); CPU seconds are OpenFOAM's ExecutionTime")


def main() -> None:
    v2_module("tabulate").main(here=HERE, descriptions=DESCRIPTIONS, notes=NOTES, load=LOAD)


if __name__ == "__main__":
    main()
