"""The stage 3 family's grid: stage 2's grid (h-2h, ``family_grid_full/``) and the two edge heights
(0.75h, 2.5h, ``edges/``) in one ``grid.csv`` (sorted by height, then velocity), and the family's
best constant chosen over all of it with grid-foam's own rule (``family_best.json``).

The two parts ran the same cells (alpha_u 0.95, alpha_p 0.3-0.9, alpha_t 0.95), criterion, check and
cap on the same solver; running the h-2h part again would cost ~60 full-mesh runs and give the same
numbers (the solver is deterministic on one machine). Run from the repository root:
``python experiments/controller/family_grid_wide/merge.py``.
"""

from __future__ import annotations

from pathlib import Path

from foam_bridge._grid import read_grid_csv, write_grid_csv
from jaxsimrl.apps.foam.evaluation.family import (
    FAMILY_BEST_JSON,
    family_best,
    family_best_json,
    grid_cap,
    summary_line,
)
from jaxsimrl.runs.atomic import atomic_write_json

HERE = Path(__file__).parent
PARTS = (HERE.parent / "family_grid_full" / "grid.csv", HERE / "edges" / "grid.csv")


def main() -> None:
    cells = [cell for part in PARTS for cell in read_grid_csv(part)]
    cells.sort(key=lambda c: (c.step_height, c.inlet_velocity))  # stable: grid order within a condition
    write_grid_csv(cells, HERE / "grid.csv")
    cap, source = grid_cap(cells)
    best = family_best(cells, cap)
    atomic_write_json(HERE / FAMILY_BEST_JSON, family_best_json(best, cells, cap, source))
    print(summary_line(best, len({c.condition for c in cells})))


if __name__ == "__main__":
    main()
