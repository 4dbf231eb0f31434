"""eval-foam's per-case oracle (controller ``case_oracle``): what a user gets who tunes by hand.

For every test case (geometry, velocity) the oracle runs a grid of constant factors on that very case
and keeps its best cell (jaxsimrl.apps.foam.evaluation.family on one condition: the fastest converged run; a
run that failed or reached the cap counts at the cap). Its result is that cell's run; its cost, what
a user pays for the tuning, is the whole grid: solver runs, SIMPLE iterations, wall and CPU time.

The grid's axes: the spec's ``oracle_alpha_u/p/t``, else the axes of ``--baseline-grid``, else those
of the small grid eval-foam runs for the best constant (``grid_alpha_u/p/t``). The k/omega axis only
applies to a run with the k/omega action; a 2-action run keeps its own k/omega factor.

The grid's runs are eval.csv rows like any other: the chosen one per case as ``case_oracle``, the
others as ``case_oracle_grid``, so the oracle's cost is the sum over both; a row's ``sample`` is its
cell's index in the grid (row-major, :func:`oracle_cells`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from foam_bridge import BUILTIN_RELAX_K_OMEGA, FoamEnvConfig, GridCell
from jaxsimrl.apps.foam.evaluation.family import family_best

ORACLE = "case_oracle"
#: eval.csv's controller of the oracle grid's runs that were not chosen.
ORACLE_GRID = "case_oracle_grid"


def _axis(values: Sequence[float | None]) -> tuple[float, ...]:
    """Distinct values in order of first appearance (None dropped)."""
    return tuple(dict.fromkeys(float(v) for v in values if v is not None))


def oracle_axes(spec: Any, cfg: FoamEnvConfig, grid: Sequence[GridCell] | None
                ) -> tuple[tuple[float, ...], ...]:
    """(alpha_u, alpha_p[, alpha_t]) axes of the oracle's grid (module docstring); one-line ValueError
    for a k/omega axis on a run without the k/omega action."""
    def pick(own: Sequence[float] | None, of_grid: tuple[float, ...], small: Sequence[float]
             ) -> tuple[float, ...]:
        return tuple(own) if own else of_grid or tuple(small)

    grid = grid or []
    axes = (pick(spec.oracle_alpha_u, _axis([c.alpha_u for c in grid]), spec.grid_alpha_u),
            pick(spec.oracle_alpha_p, _axis([c.alpha_p for c in grid]), spec.grid_alpha_p))
    if cfg.action_size == 2:
        if spec.oracle_alpha_t:
            raise ValueError(f"oracle_alpha_t: this run's policy sets only (alpha_u, alpha_p), k/omega at "
                             f"{cfg.k_omega_relaxation}; evaluate a run trained with --relax-k-omega action")
        return axes
    small_t = spec.grid_alpha_t or (BUILTIN_RELAX_K_OMEGA,)
    return (*axes, pick(spec.oracle_alpha_t, _axis([c.alpha_t for c in grid]), small_t))


def oracle_cells(axes: Sequence[Sequence[float]]) -> list[tuple[float, ...]]:
    """Every cell of the grid, row-major (the last axis varying fastest)."""
    cells: list[tuple[float, ...]] = [()]
    for axis in axes:
        cells = [(*cell, value) for cell in cells for value in axis]
    return cells


def choose(rows: Sequence[dict[str, Any]], cells: Sequence[Sequence[float]], max_iterations: int
           ) -> tuple[list[dict[str, Any]], dict[str, dict[str, Any]]]:
    """The rows with the oracle's grid runs relabelled (the chosen run per case stays ``case_oracle``,
    the rest become ``case_oracle_grid``), and per geometry -> velocity the oracle's choice and cost."""
    mine = [r for r in rows if r["controller"] == ORACLE]
    cases = list(dict.fromkeys((r["geometry"], r["velocity"]) for r in mine))
    chosen: set[int] = set()
    summary: dict[str, dict[str, Any]] = {}
    for geometry, velocity in cases:
        runs = [r for r in mine if (r["geometry"], r["velocity"]) == (geometry, velocity)]
        grid = [_cell(r, cells[r["sample"]]) for r in runs]
        best = family_best(grid, max_iterations)
        # nothing converged: every cell counts at the cap, the first is as good as any
        index = [c.factors for c in grid].index(best.factors) if best is not None else 0
        chosen.add(id(runs[index]))
        summary.setdefault(geometry, {})[f"{velocity:g}"] = _cost(runs, cells, index)
    relabelled = [r if r["controller"] != ORACLE or id(r) in chosen else {**r, "controller": ORACLE_GRID}
                  for r in rows]
    return relabelled, summary


def _cell(row: dict[str, Any], factors: Sequence[float]) -> GridCell:
    third = factors[2] if len(factors) == 3 else None
    return GridCell(factors[0], factors[1], row["iterations"], row["outcome"], row["wall_time_s"],
                    alpha_t=third, step_height=row["step_height"], inlet_velocity=row["velocity"])


def _cost(runs: Sequence[dict[str, Any]], cells: Sequence[Sequence[float]], index: int) -> dict[str, Any]:
    """eval.json's "oracle" entry of one case: the chosen factors and what the whole grid cost."""
    return {"factors": list(cells[runs[index]["sample"]]), "solver_runs": len(runs),
            "simple_iterations": sum(r["iterations"] for r in runs),
            "wall_time_s": sum(r["wall_time_s"] for r in runs),
            "cpu_time_s": sum(r["cpu_time_s"] or 0.0 for r in runs),
            "grid": [{"factors": list(cells[r["sample"]]), "outcome": r["outcome"],
                      "iterations": r["iterations"]} for r in runs]}
