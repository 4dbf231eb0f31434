"""The best constant factors for a family of cases, chosen from a grid over its conditions.

A user who tunes constants for a family (several step heights and inlet velocities) wants the factor
cell that is good on all of them, not the fastest on one: :func:`family_best` takes the cell with the
lowest geometric mean over the conditions of (iterations / that condition's best cell). A run that
failed or reached the cap counts at the cap (as the training reward does), so a cell that fails on
one condition pays for it. The geometric mean weighs a 2x on a fast case as much as a 2x on a slow
one. A condition on which no cell converged cannot rank anything (every cell would count at the cap):
it is left out and named. With one condition the choice is grid.best_cell's.

grid-foam writes the choice to ``family_best.json`` (:func:`family_best_json`); eval-foam takes its
best constant from it for a grid with several conditions, and its per-case oracle is the same choice
on one condition (the test case's own grid).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from foam_bridge import Condition, GridCell

FAMILY_BEST_JSON = "family_best.json"
RULE = ("the factor cell with the lowest geometric mean over the conditions of (iterations / that "
        "condition's best converged cell); a run that failed or reached the cap counts at the cap "
        "(max_iterations); conditions with no converged cell are left out")


@dataclass(frozen=True)
class FamilyBest:
    """The chosen cell, how it compares with each condition's best, and what the grid cost."""

    factors: tuple[float, ...]
    mean_ratio: float  # geometric mean over the ranked conditions
    worst_ratio: float
    ratios: tuple[tuple[Condition, float], ...]  # per ranked condition
    left_out: tuple[Condition, ...]  # conditions with no converged cell
    max_iterations: int
    solver_runs: int
    simple_iterations: int  # every run's iterations as run (failures at the point they failed)
    wall_time_s: float


def conditions(cells: Sequence[GridCell]) -> list[Condition]:
    """The grid's conditions in the order of first appearance."""
    return list(dict.fromkeys(c.condition for c in cells))


def grid_cap(cells: Sequence[GridCell]) -> tuple[int, str]:
    """The grid's iteration cap and where it comes from: the cells' own record (grid.csv's
    max_iterations), else (older files) the count of the runs that reached it, else the most iterations
    any run took (a lower bound: its failures count at least as its slowest run)."""
    recorded = {c.max_iterations for c in cells if c.max_iterations is not None}
    if recorded:
        return max(recorded), "recorded"
    truncated = [c.iterations for c in cells if c.outcome == "truncated"]
    if truncated:
        return max(truncated), "the runs that reached it"
    return max((c.iterations for c in cells), default=0), "not recorded: the slowest run (a lower bound)"


def family_best(cells: Sequence[GridCell], max_iterations: int) -> FamilyBest | None:
    """The family's best factor cell (module docstring); None if no condition has a converged cell.
    Every factor cell must have run on every condition (one-line ValueError otherwise); ties go to
    the first cell in grid order."""
    conds = conditions(cells)
    table = {(c.factors, c.condition): c for c in cells}
    factors = list(dict.fromkeys(c.factors for c in cells))
    if len(table) != len(cells) or len(table) != len(factors) * len(conds):
        raise ValueError(f"the grid must run every factor cell once on every condition: {len(cells)} runs, "
                         f"{len(factors)} factor cells, {len(conds)} conditions")
    best = {cond: min((c.iterations for c in cells if c.condition == cond and c.outcome == "converged"),
                      default=None) for cond in conds}
    ranked = [cond for cond in conds if best[cond]]
    if not ranked:
        return None

    def ratios(cell_factors: tuple[float, ...]) -> list[float]:
        runs = [table[(cell_factors, cond)] for cond in ranked]
        return [(r.iterations if r.outcome == "converged" else max_iterations) / best[r.condition]
                for r in runs]

    def geometric_mean(values: list[float]) -> float:
        return math.exp(sum(math.log(v) for v in values) / len(values))

    chosen = min(factors, key=lambda f: geometric_mean(ratios(f)))
    mine = ratios(chosen)
    return FamilyBest(chosen, geometric_mean(mine), max(mine), tuple(zip(ranked, mine, strict=True)),
                      tuple(c for c in conds if c not in ranked), max_iterations, len(cells),
                      sum(c.iterations for c in cells), sum(c.wall_time_s for c in cells))


def family_best_json(best: FamilyBest | None, cells: Sequence[GridCell], cap: int, cap_source: str
                     ) -> dict[str, Any]:
    """family_best.json: the rule, the choice (None if nothing converged) and the grid's cost."""
    names = ("alpha_u", "alpha_p", "alpha_t")
    chosen = None if best is None else {
        "factors": dict(zip(names, best.factors, strict=False)),
        "mean_ratio": best.mean_ratio, "worst_ratio": best.worst_ratio,
        "ratios": [{"step_height": h, "inlet_velocity": v, "ratio": r} for (h, v), r in best.ratios],
        "left_out": [{"step_height": h, "inlet_velocity": v} for h, v in best.left_out]}
    return {"rule": RULE, "max_iterations": cap,
            "max_iterations_source": cap_source,
            "conditions": [{"step_height": h, "inlet_velocity": v} for h, v in conditions(cells)],
            "best": chosen,
            "cost": {"solver_runs": len(cells), "simple_iterations": sum(c.iterations for c in cells),
                     "wall_time_s": sum(c.wall_time_s for c in cells)}}


def summary_line(best: FamilyBest | None, n_conditions: int) -> str:
    """One line: the chosen cell, its mean and worst ratio, and the grid's cost."""
    if best is None:
        return f"family best over {n_conditions} conditions: no cell converged on any condition"
    names = ("alpha_u", "alpha_p", "alpha_t")
    cell = " ".join(f"{n}={f:g}" for n, f in zip(names, best.factors, strict=False))
    left = f" ({len(best.left_out)} left out: nothing converged)" if best.left_out else ""
    return (f"family best over {n_conditions} conditions{left}: {cell} -> geometric mean ratio "
            f"{best.mean_ratio:.3f}, worst {best.worst_ratio:.3f}; grid cost {best.solver_runs} solver runs, "
            f"{best.simple_iterations:,} SIMPLE iterations")
