# SPDX-License-Identifier: GPL-3.0-or-later
"""The cost of generated cases, from the generator's manifests (manifests/: copies of generated.json of
run.sh's sets): per resolution and kind, the specs drawn, rejected (and why), cells, and the own runs'
iterations and CPU seconds. Writes manifests/table.md.

    python experiments/controller/generated-v1-setup/manifest_table.py
"""

from __future__ import annotations

import json
import statistics
from collections import Counter
from pathlib import Path

from foam_bridge import GEOMETRY_KINDS

HERE = Path(__file__).resolve().parent / "manifests"


def rows(name: str) -> list[str]:
    manifest = json.loads((HERE / name).read_text())
    out = []
    for kind in (*GEOMETRY_KINDS, "all"):
        cases = [c for c in manifest["cases"] if kind in ("all", c["spec"]["kind"])]
        rejected = [r for r in manifest["rejected"] if kind in ("all", r["spec"]["kind"])]
        why = Counter("crashed" if "crashed" in r["reason"] else "diverged" if "diverged" in r["reason"]
                      else "not converged" for r in rejected)
        its, cpu = [c["iterations"] for c in cases], [c["cpu_s"] for c in cases]
        cells = [c["cells"] for c in cases]
        out.append(f"| {name} | {manifest['resolution']:g} | {kind} | {len(cases) + len(rejected)} | "
                   f"{len(rejected)} ({', '.join(f'{n} {w}' for w, n in why.items()) or '-'}) | "
                   f"{min(cells):,}-{max(cells):,} | {statistics.median(its):g} ({min(its)}-{max(its)}) | "
                   f"{statistics.median(cpu):.2f} ({min(cpu):.2f}-{max(cpu):.2f}) | {sum(cpu):.0f} |")
    return out


def main() -> None:
    lines = ["| manifest | resolution | kind | drawn | rejected | cells | own iterations median (range) | "
             "own CPU s median (range) | own CPU s in all |", "|---|---|---|---|---|---|---|---|---|"]
    for name in sorted(p.name for p in HERE.glob("*.json")):
        lines += rows(name)
    (HERE / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
