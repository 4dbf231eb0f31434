# SPDX-License-Identifier: GPL-3.0-or-later
"""Build the heldout-v3 cases: each a plain simpleFoam case, meshed, ready to run.

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/controller/heldout-v3/prepare.py \
        [runs/heldout-v3] [--only NAME ...] [--evaluation]

The builders are in cases.py; the building is heldout-v2's prepare.py. Deterministic.
"""

from __future__ import annotations

from pathlib import Path

from cases import CASES, v2_module

HERE = Path(__file__).resolve().parent


def main() -> None:
    v2_module("prepare").main(cases=CASES, here=HERE, description=__doc__)


if __name__ == "__main__":
    main()
