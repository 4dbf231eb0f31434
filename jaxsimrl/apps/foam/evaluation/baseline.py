"""eval-foam's constant controllers: the best constant (from a grid-foam grid.csv, or a small grid run
here), the tutorial's defaults, and a constant's factors as an action of the evaluated run."""

from __future__ import annotations

import csv
import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from foam_bridge import (
    BUILTIN_RELAX_K_OMEGA,
    FoamEnvConfig,
    best_cell,
    plot_grid,
    read_grid_csv,
    run_grid,
    write_grid_csv,
)
from jaxsimrl.apps.foam.evaluation.eval_spec import GRID_CSV, GRID_PNG, TUTORIAL_DEFAULTS, EvalSpec
from jaxsimrl.apps.foam.evaluation.family import conditions, family_best, family_best_json, grid_cap


@dataclass(frozen=True)
class Baseline:
    """The best constant factors and where they come from."""

    alpha_u: float
    alpha_p: float
    source: str
    grid_iterations: int | None  # the best cell's; None for a family's best (no one condition's)
    alpha_t: float | None = None  # the k/omega factor of a 3-D grid's best cell
    #: A grid over several conditions: family_best_json (the rule, the mean and worst ratio, the cost).
    family: dict[str, Any] | None = None

    @property
    def factors(self) -> tuple[float, ...]:
        return (self.alpha_u, self.alpha_p, *(() if self.alpha_t is None else (self.alpha_t,)))


def as_action(cfg: FoamEnvConfig, factors: Sequence[float]) -> tuple[float, ...]:
    """A constant's factors as an action of ``cfg``. A 2-factor constant on a config with the k/omega
    action keeps the k/omega factor 2-factor runs had (BUILTIN_RELAX_K_OMEGA, the paper's and the
    tutorial's 0.8); a 3-factor constant needs that action (one-line ValueError otherwise)."""
    values = tuple(float(f) for f in factors)
    if len(values) == cfg.action_size:
        return values
    if len(values) == 2:
        return (*values, BUILTIN_RELAX_K_OMEGA)
    raise ValueError(f"the constant {values} sets alpha_t (k/omega) but this run's policy sets only "
                     f"(alpha_u, alpha_p), k/omega at {cfg.k_omega_relaxation}: evaluate a run trained with "
                     f"--relax-k-omega action, or give a grid without alpha_t")


def read_baseline_grid(path: str | Path) -> list[Any]:
    """The cells of a grid-foam grid.csv; one-line ValueError for a missing or bad file."""
    try:
        cells = read_grid_csv(path)
    except OSError as err:
        raise ValueError(f"--baseline-grid {path}: cannot read it ({err.strerror})") from None
    except (KeyError, ValueError, TypeError, csv.Error) as err:
        raise ValueError(f"--baseline-grid {path}: not a grid-foam grid.csv ({type(err).__name__}: "
                         f"{err})") from None
    return cells


def baseline_from_csv(path: str | Path, cells: Sequence[Any] | None = None) -> Baseline:
    """The best constant of a grid-foam grid.csv (``cells``: already read from it): its best converged
    cell, or over several conditions the cell best for the family (jaxsimrl.apps.foam.evaluation.family, each
    failure at the grid's cap); one-line ValueError for a missing or bad file or no converged cell."""
    cells = read_baseline_grid(path) if cells is None else cells
    family = None
    if len(conditions(cells)) > 1:
        cap, cap_source = grid_cap(cells)
        try:
            chosen = family_best(cells, cap)
        except ValueError as err:
            raise ValueError(f"--baseline-grid {path}: {err}") from None
        best = None if chosen is None else next(c for c in cells if c.factors == chosen.factors)
        family = family_best_json(chosen, cells, cap, cap_source)
        source = (f"grid.csv {path} (the cell best for its {len(conditions(cells))} conditions: lowest "
                  f"geometric mean of iterations / each condition's best, failures at the cap {cap})")
    else:
        best = best_cell(cells)
        source = f"grid.csv {path} (best converged cell, as recorded there)"
    if best is None:
        raise ValueError(f"--baseline-grid {path}: no converged cell to take the best constant from")
    if not all(0 < f <= 1 for f in best.factors):
        raise ValueError(f"--baseline-grid {path}: best cell {best.factors} is outside (0, 1]")
    return Baseline(best.alpha_u, best.alpha_p, source, None if family else best.iterations, best.alpha_t,
                    family)


def baseline_from_grid(spec: EvalSpec, cfg: FoamEnvConfig, velocity: float, geometry: str,
                       say: Callable[[str], None]) -> Baseline:
    """Run the small constant grid at ``velocity`` on ``geometry``; writes it to the output directory."""
    def on_cell(cell: Any) -> None:
        say(f"grid {factors_text(cell.factors)}: {cell.outcome} @ {cell.iterations} it")

    alpha_t = (spec.grid_alpha_t or (BUILTIN_RELAX_K_OMEGA,)) if cfg.action_size == 3 else None
    cells = run_grid(dataclasses.replace(cfg, inlet_velocity=velocity), spec.grid_alpha_u, spec.grid_alpha_p,
                     pool=spec.pool, on_cell=on_cell, alpha_t=alpha_t)
    out = spec.output_dir
    write_grid_csv(cells, out / GRID_CSV)
    title = f"best constant search: V = {velocity:g} m/s, {geometry}, test criterion"
    plot_grid(cells, out / GRID_PNG, title)
    best = best_cell(cells)
    if best is None:
        raise ValueError(f"no cell of the baseline grid converged at {velocity:g} m/s on {geometry} (see "
                         f"{out / GRID_CSV}); give --baseline-grid or other --grid-alpha-u/--grid-alpha-p")
    source = (f"grid run by eval-foam at V = {velocity:g} m/s on {geometry}: alpha_u in "
              f"{list(spec.grid_alpha_u)}, alpha_p in {list(spec.grid_alpha_p)}"
              + ("" if alpha_t is None else f", alpha_t in {list(alpha_t)}") + f" ({out / GRID_CSV})")
    return Baseline(best.alpha_u, best.alpha_p, source, best.iterations, best.alpha_t)


def constant_factors(baseline: Baseline | None, cfg: FoamEnvConfig,
                     oracle: Sequence[Sequence[float]] = ()) -> list[tuple[float, ...]]:
    """The constant controllers' actions, the oracle's grid cells included (the env's action box must
    hold them)."""
    chosen = [TUTORIAL_DEFAULTS] if baseline is None else [baseline.factors, TUTORIAL_DEFAULTS]
    return [as_action(cfg, factors) for factors in (*chosen, *oracle)]


def factors_text(factors: Sequence[float]) -> str:
    """"(0.9, 0.8)": factors as the messages and eval.json write them."""
    return "(" + ", ".join(f"{f:g}" for f in factors) + ")"
