"""``jaxsimrl eval-foam RUN_DIR``: a train-foam policy against baselines (logic in evaluation.foam_eval).

    jaxsimrl eval-foam runs/foam-1 --pool 4 --baseline-grid runs/grid/grid.csv

Writes RUN_DIR/eval/ (or --out): eval.json, eval.csv, box_V<v>.png, mean_V<v>.png, factors.png. Bad input
(not a run directory, no checkpoint, a velocity <= 0, a bad grid CSV, OpenFOAM missing) is one line on
stderr and exit code 2, before any solver starts.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

from foam_bridge import OpenFOAMNotFoundError, find_openfoam
from jaxsimrl.apps.foam.cli.grid_foam import add_confirm_argument, relaxation_factor
from jaxsimrl.apps.foam.evaluation.eval import evaluate_foam
from jaxsimrl.apps.foam.evaluation.eval_spec import CONTROLLERS, DEFAULT_CONTROLLERS, EvalSpec
from jaxsimrl.cli.errors import fail, positive_float, positive_int, seed_type
from jaxsimrl.cli.progress import RunProgress


def register(subparsers: Any) -> None:
    """Add the ``eval-foam`` subcommand."""
    parser = subparsers.add_parser(
        "eval-foam", help="evaluate a train-foam policy against constant, default and random factors",
        description="The paper's test protocol on RUN_DIR's last checkpoint: inlet velocities 25, 50, "
        "75 m/s, the test criterion, step heights h and 2h, the full mesh. Controllers: the learned policy "
        "(deterministic: one run per cell; stochastic: --samples runs), the best constant factors, the "
        "tutorial's defaults (U 0.9, p 0.8; k/omega 0.8 with the k/omega action) and random factors "
        "(--samples runs); on request (--controllers ... case_oracle) the best constant of a grid on each "
        "test case, with that grid's cost. Every run reports SIMPLE "
        "iterations, wall time and linear-solver iterations, and with --reference-iterations the error of "
        "its final U field against a long reference run.")
    parser.add_argument("run_dir", metavar="RUN_DIR", help="a run directory written by train-foam")
    parser.add_argument("--velocities", type=positive_float, nargs="+", metavar="V",
                        default=[25.0, 50.0, 75.0], help="inlet velocities in m/s (default: 25 50 75)")
    parser.add_argument("--step-height", type=positive_float, nargs="+", metavar="M", dest="step_height",
                        help="step heights in metres (default: 0.0127 0.0254, i.e. h and 2h)")
    parser.add_argument("--mesh-scale", type=positive_float, default=1.0,
                        help="mesh resolution factor (1.0 = the full 20,540-cell mesh; default 1.0)")
    parser.add_argument("--pool", type=positive_int, default=os.cpu_count() or 1,
                        help="worker processes, one simpleFoam each (default: the CPU count)")
    parser.add_argument("--samples", type=positive_int, default=10,
                        help="runs per cell of the stochastic policy and of random factors (default 10)")
    parser.add_argument("--baseline-grid", metavar="GRID.csv", type=Path,
                        help="a grid.csv of grid-foam: its converged cell with the fewest iterations is the "
                        "best constant; of a grid over several conditions, the cell best for that family "
                        "(lowest geometric mean of iterations / each condition's best) (default: run a small "
                        "grid at the first velocity on the first geometry)")
    parser.add_argument("--grid-alpha-u", type=relaxation_factor, nargs="+", default=[0.8, 0.9, 0.95],
                        metavar="A", help="alpha_u of that small grid (default 0.8 0.9 0.95)")
    parser.add_argument("--grid-alpha-p", type=relaxation_factor, nargs="+", default=[0.8, 0.9, 0.95],
                        metavar="B", help="alpha_p of that small grid (default 0.8 0.9 0.95)")
    parser.add_argument("--grid-alpha-t", type=relaxation_factor, nargs="+", default=None, metavar="T",
                        help="alpha_t (k/omega) of that small grid, for a run with the k/omega action "
                        "(default 0.8, the paper's)")
    for axis, name in (("u", "alpha_u"), ("p", "alpha_p"), ("t", "alpha_t (k/omega)")):
        parser.add_argument(f"--oracle-alpha-{axis}", type=relaxation_factor, nargs="+", default=None,
                            metavar="F", help=f"{name} of the case_oracle's grid on every test case "
                            "(default: the --baseline-grid's, else the small grid's)")
    parser.add_argument("--seed", type=seed_type(), default=0,
                        help="seeds the sampled and random actions (default 0): the same command gives the "
                        "same numbers")
    parser.add_argument("--controllers", nargs="+", choices=CONTROLLERS, default=list(DEFAULT_CONTROLLERS),
                        metavar="NAME", help=f"the controllers to run, of {' '.join(CONTROLLERS)} (default: "
                        f"{' '.join(DEFAULT_CONTROLLERS)}; case_oracle runs a grid per test case)")
    parser.add_argument("--reference-iterations", type=positive_int, metavar="N",
                        help="first run the best constant (else the defaults) for N iterations per geometry "
                        "and velocity, and report each run's U error against it (default: no reference)")
    parser.add_argument("--reference-cache", type=Path, metavar="DIR",
                        help="reuse the reference runs stored in DIR and store new ones there; an entry is "
                        "keyed by everything the solver is given, so any change is a new run (default: "
                        "run every reference)")
    add_confirm_argument(parser)
    parser.add_argument("--out", metavar="DIR", type=Path, help="output directory (default RUN_DIR/eval)")
    parser.set_defaults(func=run_eval_foam)


def _tuple(values: list[float] | None) -> tuple[float, ...] | None:
    return None if values is None else tuple(values)


def _check_openfoam() -> None:
    try:
        find_openfoam()
    except OpenFOAMNotFoundError as err:
        fail(str(err))


def run_eval_foam(args: argparse.Namespace) -> int:
    """Run the evaluation; print progress and the table of results."""
    spec = EvalSpec(run_dir=Path(args.run_dir), velocities=tuple(args.velocities),
                    step_heights=None if args.step_height is None else tuple(args.step_height),
                    mesh_scale=args.mesh_scale, samples=args.samples, pool=args.pool, seed=args.seed,
                    baseline_grid=args.baseline_grid, grid_alpha_u=tuple(args.grid_alpha_u),
                    grid_alpha_p=tuple(args.grid_alpha_p), out=args.out,
                    grid_alpha_t=None if args.grid_alpha_t is None else tuple(args.grid_alpha_t),
                    controllers=tuple(args.controllers), reference_iterations=args.reference_iterations,
                    reference_cache=args.reference_cache, confirm_alpha_u=args.confirm_alpha_u,
                    **{f"oracle_alpha_{a}": _tuple(getattr(args, f"oracle_alpha_{a}")) for a in "upt"})
    _check_openfoam()
    with EvalProgress() as progress:
        try:
            report = evaluate_foam(spec, progress.advance, progress.say)
        except ValueError as err:
            fail(str(err))
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the pool has stopped every solver
            progress.say(f"stopped: {spec.output_dir}/eval.json and eval.csv are written at the end, so "
                         f"this evaluation left none")
            raise
    progress.console.print(results_table(report))
    for line in oracle_lines(report):
        progress.say(line)
    progress.console.print(f"wrote {spec.output_dir}/eval.json, eval.csv and the figures")
    return 0


class EvalProgress(RunProgress):
    """eval-foam's progress: one step per finished run (cli.progress)."""

    def __init__(self) -> None:
        super().__init__("eval-foam")

    def advance(self, result: Any, done: int, total: int) -> None:
        job = result.job
        self.step(f"{job.geometry} V={job.velocity:g} {job.controller} #{job.sample}: {result.outcome} @ "
                  f"{result.iterations} it, {result.wall_time_s:.1f} s", done, total)


#: Short controller names for the terminal table.
SHORT_NAMES = {"learned_deterministic": "learned mean", "learned_stochastic": "learned sampled",
               "best_constant": "best constant", "tutorial_defaults": "defaults", "random": "random",
               "residual_rule": "residual rule", "bandit": "bandit", "case_oracle": "case oracle"}


def results_table(report: dict[str, Any]) -> Any:
    """A rich table: per geometry, velocity and controller, the costs (mean +- std of converged runs)."""
    from rich import box
    from rich.table import Table

    table = Table(title="eval-foam: mean +- std over the converged runs", box=box.SIMPLE_HEAD, padding=(0, 1))
    with_error = report.get("reference") is not None
    checked = report["case"].get("confirm_alpha_u") is not None
    columns = ("geom", "V", "controller", "conv.", "SIMPLE its", "wall s", "CPU s", "linear its")
    for column in columns + (("U error",) if with_error else ()) + (("failed checks",) if checked else ()):
        table.add_column(column, justify="left" if column in ("geom", "controller") else "right")
    for geometry in report["geometries"]:
        for velocity in report["velocities"]:
            for controller, cells in report["results"].items():
                cell = cells[geometry][f"{velocity:g}"]
                converged = f"{cell['converged']}/{len(cell['runs'])}"
                row = [geometry, f"{velocity:g}", SHORT_NAMES.get(controller, controller), converged,
                       _pm(cell["iterations"], 0), _pm(cell["wall_time_s"], 1), _pm(cell["cpu_time_s"], 1),
                       _pm(cell["linear_iterations"], 0)]
                row += [_pm(cell["u_error"], 3)] if with_error else []
                table.add_row(*row, *([str(cell["failed_checks"])] if checked else []))
    return table


def oracle_lines(report: dict[str, Any]) -> list[str]:
    """One line per test case of the case oracle (if it ran): its choice and what its grid cost."""
    lines = []
    for geometry, velocities in report["results"].get("case_oracle", {}).items():
        for velocity, cell in velocities.items():
            oracle = cell["oracle"]
            factors = ", ".join(f"{f:g}" for f in oracle["factors"])
            runs, iterations = oracle["solver_runs"], oracle["simple_iterations"]
            lines.append(f"case oracle {geometry} V={velocity}: ({factors}) of a grid of {runs} runs, "
                         f"{iterations:,} SIMPLE iterations, {oracle['wall_time_s']:.0f} s")
    return lines


def _pm(summary: dict[str, Any], digits: int) -> str:
    if summary["mean"] is None:
        return "-"
    return f"{summary['mean']:.{digits}f}±{summary['std']:.{digits}f}"
