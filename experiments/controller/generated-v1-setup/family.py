# SPDX-License-Identifier: GPL-3.0-or-later
"""The training family of run.sh, one case directory per line: the plain SIMPLE cases of a generated set
at resolution 0.7 and the SIMPLEC cases of the same seed at full size (resolution 1.0), as the ranking
check found (experiments/controller/generated-ranking/: coarse meshes rank plain SIMPLE settings as the
full size does from 0.7 on, SIMPLEC settings at no coarse resolution).

    python experiments/controller/generated-v1-setup/family.py \
        runs/generated-train-r0.7 runs/generated-train-r1
"""

from __future__ import annotations

import sys
from pathlib import Path

from foam_bridge import read_generated


def cases(coarse: Path, full: Path) -> list[Path]:
    """Plain SIMPLE cases from ``coarse``, SIMPLEC cases from ``full`` (each as its generator accepted it)."""
    chosen = []
    for directory, algorithm in ((coarse, "SIMPLE"), (full, "SIMPLEC")):
        chosen += [directory / entry["name"] for entry in read_generated(directory)["cases"]
                   if entry["spec"]["algorithm"] == algorithm]
    return chosen


if __name__ == "__main__":
    print("\n".join(str(path) for path in cases(Path(sys.argv[1]), Path(sys.argv[2]))))
