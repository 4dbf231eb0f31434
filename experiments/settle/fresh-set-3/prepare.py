# SPDX-License-Identifier: GPL-3.0-or-later
"""Build the candidates of issue 56's third fresh set: each a plain simpleFoam case, meshed, ready to run.

    WM_PROJECT_DIR=/usr/share/openfoam .venv/bin/python experiments/settle/fresh-set-3/prepare.py \
        [runs/fresh-set-3] [--only NAME ...]

The builders are in cases.py; the building is heldout-v2's prepare.py (through the first fresh set's
v2_module). Deterministic: two builds are the same files, logs aside.
"""

from __future__ import annotations

from pathlib import Path

from cases import CASES, v2_module

HERE = Path(__file__).resolve().parent


def main() -> None:
    v2_module("prepare").main(cases=CASES, here=HERE, description=__doc__)


if __name__ == "__main__":
    main()
