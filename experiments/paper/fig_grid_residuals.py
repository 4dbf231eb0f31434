"""Constant-factor heatmap and typical residual histories (the paper's Fig. "heatmap").

1. Runs one env episode with constant factors for every (alpha_u, alpha_p) pair of a small grid
   (foam_bridge._grid.run_grid: SIMPLEC, k/omega 0.8, inlet U_ref = 44.2 m/s, the local pool) and draws
   the heatmap with foam_bridge._grid.plot_grid.
2. Reruns the best pair ("good") and the slowest other pair ("bad") as single uninterrupted simpleFoam
   runs of the same episode case (experiments/paper/fig_cfd_validation.run_uninterrupted), which gives
   the whole log, and checks that they take the grid's iteration counts (chunked == uninterrupted).
3. Plots the paper's state / U_ref^2 and the initial residuals of U, p, k, omega against the iteration
   for both pairs.

Writes ``--out``/fig_grid_heatmap.png, fig_grid_residuals.png and grid_residuals.json.

    python experiments/paper/fig_grid_residuals.py                        # 3 x 3 grid, full mesh, pool 2
    python experiments/paper/fig_grid_residuals.py --alpha-u 0.7 0.95 --alpha-p 0.5 0.95   # 4 pairs
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

# The sibling script: Python puts this script's directory first on sys.path.
from fig_cfd_validation import (
    RELAX_K_OMEGA,
    SolverRun,
    new_figure,
    residual_history,
    run_uninterrupted,
    save_png,
)

from foam_bridge._config import TEST_CONVERGENCE, TRAIN_CONVERGENCE, U_REF, FoamEnvConfig
from foam_bridge._grid import GridCell, best_cell, check_factors, grid_config, plot_grid, run_grid
from foam_bridge._logparse import field_residual
from foam_bridge._openfoam import find_openfoam
from jaxsimrl.runs.atomic import atomic_write_json

CRITERIA = {"train": TRAIN_CONVERGENCE, "test": TEST_CONVERGENCE}
FIELDS = ("U", "p", "k", "omega")
COLOURS = {"U": "tab:blue", "p": "tab:orange", "k": "tab:green", "omega": "tab:red"}


def grid_cfg(mesh_scale: float, criterion: str, max_iterations: int) -> FoamEnvConfig:
    """The grid's env config: SIMPLEC, k/omega 0.8, inlet U_ref, the chosen convergence criterion."""
    return FoamEnvConfig(mesh_scale=mesh_scale, simple_variant="SIMPLEC", relax_k_omega=RELAX_K_OMEGA,
                         inlet_velocity=U_REF, max_iterations=max_iterations,
                         convergence=dict(CRITERIA[criterion])).validate()


def good_and_bad(cells: Sequence[GridCell]) -> tuple[GridCell, GridCell]:
    """The best converged cell and the slowest other one (failures count as their iteration)."""
    good = best_cell(cells)
    if good is None:
        raise RuntimeError("no cell of the grid converged: nothing to call a good pair")
    others = [c for c in cells if c is not good]
    if not others:
        raise RuntimeError("the grid has one cell: give at least two pairs")
    return good, max(others, key=lambda c: (c.outcome != "converged", c.iterations))


def rerun(cfg: FoamEnvConfig, cells: Sequence[GridCell], root: Path, pool: int) -> list[SolverRun]:
    """The cells' pairs as uninterrupted runs, ``pool`` at a time (threads: each waits on a solver)."""
    openfoam = find_openfoam()
    with ThreadPoolExecutor(max_workers=pool) as executor:
        futures = [executor.submit(run_uninterrupted, cfg, root / f"rerun_{i}", cell.alpha_u, cell.alpha_p,
                                   openfoam) for i, cell in enumerate(cells)]
        return [future.result() for future in futures]


def run_iterations(run: SolverRun) -> int:
    """Iterations of an uninterrupted run as the env counts them (converged, capped or failed)."""
    parser = run.parser
    if parser.converged_at is not None:
        return parser.converged_at
    return parser.failed_at if parser.failed_at is not None else parser.completed


def plot_histories(pairs: Sequence[GridCell], runs: Sequence[SolverRun], criterion: dict[str, float],
                   path: Path, title: str) -> None:
    """State / U_ref^2 of both runs (left), then each run's initial residuals (one panel each)."""
    fig = new_figure(14, 4.4)
    axes = fig.subplots(1, 1 + len(runs))
    for cell, run, style in zip(pairs, runs, ("-", "--"), strict=True):
        iterations = np.array(sorted(run.states))
        axes[0].plot(iterations, [run.states[i] for i in iterations], style, color="black",
                     label=_pair_label(cell))
    # the good run would be a sliver beside a capped bad one: show a few times its length
    longest = max(max(run.states) for run in runs)
    axes[0].set_xlim(0, min(longest, 4 * max(runs[0].states)))
    axes[0].set_xlabel("SIMPLE iteration")
    axes[0].set_ylabel(r"state $= (\overline{|U_b|^2} + \overline{|U_m|^2}) / U_\mathrm{ref}^2$")
    axes[0].legend(fontsize=8)
    axes[0].set_title("the environment's state", fontsize=10)
    for ax, cell, run in zip(axes[1:], pairs, runs, strict=True):
        history = residual_history(run.parser, FIELDS)
        for name in FIELDS:
            ax.semilogy(np.arange(1, history[name].size + 1), history[name], color=COLOURS[name],
                        linewidth=1, label=name)
            if name in criterion:
                ax.axhline(criterion[name], color=COLOURS[name], linestyle=":", linewidth=1)
        ax.set_xlabel("SIMPLE iteration")
        ax.set_ylabel("initial residual")
        ax.set_title(f"{_pair_label(cell)}: {cell.outcome} at {cell.iterations}", fontsize=10)
        ax.legend(fontsize=8, ncol=2, loc="upper right")
        ax.grid(alpha=0.3, which="both")
    fig.suptitle(title + " (dotted: the convergence criterion)", fontsize=10)
    save_png(fig, path)


def _pair_label(cell: GridCell) -> str:
    return f"alpha_u = {cell.alpha_u:g}, alpha_p = {cell.alpha_p:g}"


def summary(args: argparse.Namespace, cells: Sequence[GridCell], pairs: Sequence[GridCell],
            runs: Sequence[SolverRun], wall_s: float) -> dict[str, Any]:
    """The numbers of grid_residuals.json."""
    histories = {}
    for role, cell, run in zip(("good", "bad"), pairs, runs, strict=True):
        histories[role] = {
            "alpha_u": cell.alpha_u, "alpha_p": cell.alpha_p, "grid_outcome": cell.outcome,
            "grid_iterations": cell.iterations, "uninterrupted_iterations": run_iterations(run),
            "final_initial_residuals": {n: field_residual(run.parser.residuals, n) for n in FIELDS},
            "uninterrupted_wall_time_s": round(run.wall_s, 2)}
    return {
        "created_utc": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "load_average_1_5_15": [round(v, 2) for v in os.getloadavg()],
        "mesh_scale": args.mesh_scale, "cells": runs[0].cells, "pool": args.pool,
        "simple_variant": "SIMPLEC", "alpha_k_omega": RELAX_K_OMEGA, "inlet_velocity_m_s": U_REF,
        "criterion": args.criterion, "convergence": dict(CRITERIA[args.criterion]),
        "max_iterations": args.max_iterations,
        "grid": [dataclasses.asdict(c) | {"wall_time_s": round(c.wall_time_s, 2)} for c in cells],
        "histories": histories, "script_wall_time_s": round(wall_s, 1),
    }


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--alpha-u", type=float, nargs="+", default=[0.7, 0.9, 0.95])
    parser.add_argument("--alpha-p", type=float, nargs="+", default=[0.5, 0.8, 0.95])
    parser.add_argument("--mesh-scale", type=float, default=1.0, help="1.0 = 20,540 cells (default)")
    parser.add_argument("--pool", type=int, default=2, help="solvers at once (default 2)")
    parser.add_argument("--criterion", choices=sorted(CRITERIA), default="test",
                        help="the paper's training (1e-3) or test (5e-4, its heatmap's) criterion")
    parser.add_argument("--max-iterations", type=int, default=4000)
    parser.add_argument("--out", type=Path, default=Path(__file__).parent, help="directory for PNGs + JSON")
    args = parser.parse_args(argv)
    if len(args.alpha_u) * len(args.alpha_p) < 2:
        parser.error("give at least two (alpha_u, alpha_p) pairs")
    if args.pool < 1:
        parser.error(f"--pool must be >= 1, got {args.pool}")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Grid, reruns of the good and the bad pair, the two figures and grid_residuals.json."""
    args = parse_args(argv)
    try:
        check_factors(args.alpha_u, "--alpha-u")
        check_factors(args.alpha_p, "--alpha-p")
        cfg = grid_config(grid_cfg(args.mesh_scale, args.criterion, args.max_iterations), args.alpha_u,
                          args.alpha_p)
    except ValueError as error:
        print(f"fig_grid_residuals: {error}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="grid_residuals_") as scratch:
        cells = run_grid(cfg, args.alpha_u, args.alpha_p, pool=args.pool, work_dir=Path(scratch) / "grid",
                         on_cell=lambda c: print(f"  {_pair_label(c)}: {c.outcome} at {c.iterations}"))
        pairs = good_and_bad(cells)
        runs = rerun(cfg, pairs, Path(scratch), args.pool)
    solver = f"{runs[0].cells:,} cells, SIMPLEC, k/omega {RELAX_K_OMEGA}"
    flow = f"U = {U_REF} m/s, {args.criterion} criterion"
    setting = f"{solver}, {flow}"
    plot_grid(cells, args.out / "fig_grid_heatmap.png", f"Iterations to convergence\n{solver}\n{flow}")
    plot_histories(pairs, runs, dict(CRITERIA[args.criterion]), args.out / "fig_grid_residuals.png",
                   f"Good and bad constant factors, {setting}")
    numbers = summary(args, cells, pairs, runs, time.monotonic() - start)
    atomic_write_json(args.out / "grid_residuals.json", numbers)
    for role, record in numbers["histories"].items():
        print(f"{role}: ({record['alpha_u']:g}, {record['alpha_p']:g}) grid {record['grid_iterations']}, "
              f"uninterrupted {record['uninterrupted_iterations']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
