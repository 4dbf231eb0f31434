"""``jaxsimrl grid-foam``: the constant-factor grid study on simpleFoam (logic in foam_bridge._grid).

    jaxsimrl grid-foam --alpha-u 0.5 0.7 0.9 --alpha-p 0.5 0.7 0.9 --mesh-scale 0.5 --pool 2 --out runs/grid

Writes OUT/grid.csv (alpha_u, alpha_p, iterations, outcome, wall_time_s) and OUT/grid.png (heatmap).
``--alpha-t A [A ...]`` adds the k/omega factor as a third axis: grid.csv gains an alpha_t column and
there is one heatmap per alpha_t, OUT/grid_alpha_t_<A>.png.
Several ``--step-height`` and/or ``--inlet-velocity`` values run every factor cell on every (height,
velocity) condition: grid.csv gains step_height, inlet_velocity (and max_iterations) columns, the
heatmaps are per condition (OUT/grid_<geometry>_V<v>[_alpha_t_<A>].png) and OUT/family_best.json holds
the cell best for the family (jaxsimrl.apps.foam.evaluation.family) and the grid's cost; one line sums it up.
grid.csv is rewritten after every finished cell: a grid stopped part-way keeps what it ran.
Bad input (factor outside (0, 1], empty list, bad mesh scale, pool < 1, OUT an existing file, OpenFOAM
missing) is one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from pathlib import Path
from typing import Any

from foam_bridge import (
    BUILTIN_RELAX_K_OMEGA,
    FOLLOW_ALPHA_U,
    K_OMEGA_ACTION,
    MESH_SCALE_USABLE_MIN,
    STEP_HEIGHT_H,
    TEST_CONVERGENCE,
    TRAIN_CONVERGENCE,
    FoamEnvConfig,
    OpenFOAMNotFoundError,
    best_cell,
    find_openfoam,
    plot_grid,
    plot_grid_slices,
    run_grid,
    write_grid_csv,
)
from jaxsimrl.apps.foam.evaluation.eval_spec import geometry_name
from jaxsimrl.apps.foam.evaluation.family import (
    FAMILY_BEST_JSON,
    conditions,
    family_best,
    family_best_json,
    summary_line,
)
from jaxsimrl.cli.errors import fail, positive_float, positive_int
from jaxsimrl.cli.progress import RunProgress
from jaxsimrl.runs.atomic import atomic_write_json

CRITERIA = ("train", "test")


def relaxation_factor(text: str) -> float:
    """argparse type: an under-relaxation factor in (0, 1]."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a relaxation factor in (0, 1], got {text!r}") from None
    if not (math.isfinite(value) and 0 < value <= 1):
        raise argparse.ArgumentTypeError(f"expected a relaxation factor in (0, 1], got {text!r}")
    return value


def k_omega_factor(text: str) -> float | str:
    """argparse type: a relaxation factor in (0, 1] or ``alpha_u`` (k and omega follow alpha_u)."""
    return FOLLOW_ALPHA_U if text == FOLLOW_ALPHA_U else relaxation_factor(text)


def k_omega_setting(text: str) -> float | str:
    """argparse type of train-foam's --relax-k-omega: a factor, ``alpha_u`` or ``action`` (a third action)."""
    return K_OMEGA_ACTION if text == K_OMEGA_ACTION else k_omega_factor(text)


def check_factor(text: str) -> float:
    """argparse type: the relaxation of the convergence check (FoamEnvConfig.confirm_alpha_u), in (0, 1)."""
    value = relaxation_factor(text)
    if value == 1:  # unrelaxed, SIMPLEC (rAtU = 1/(1/rAU - H1)) breaks down: the check ran no iteration
        raise argparse.ArgumentTypeError(f"expected a relaxation factor in (0, 1), got {text!r}")
    return value


def add_confirm_argument(parser: argparse.ArgumentParser) -> None:
    """``--confirm-alpha-u A``: a convergence test relaxation cannot move (FoamEnvConfig.confirm_alpha_u)."""
    parser.add_argument("--confirm-alpha-u", type=check_factor, metavar="A", dest="confirm_alpha_u",
                        help="a convergence test relaxation cannot move: the criterion must also hold "
                        "for the residuals normalised at alpha_u = A (e.g. 0.9), checked by one more SIMPLE "
                        "iteration from the run's fields; a run that fails goes on (default: the solver's "
                        "own test only, as the paper)")


def register(subparsers: Any) -> None:
    """Add the ``grid-foam`` subcommand."""
    parser = subparsers.add_parser(
        "grid-foam",
        help="iterations to convergence of simpleFoam for every constant (alpha_u, alpha_p) on a grid",
        description="Run the backward-facing step with constant relaxation factors for every pair on a "
        "grid (in parallel) and write OUT/grid.csv and a heatmap OUT/grid.png. OUT/grid.csv is rewritten "
        "after every finished cell, so a grid stopped part-way keeps the runs it finished.",
    )
    parser.add_argument("--alpha-u", type=relaxation_factor, nargs="+", required=True, metavar="A",
                        help="momentum relaxation factors, each in (0, 1]")
    parser.add_argument("--alpha-p", type=relaxation_factor, nargs="+", required=True, metavar="B",
                        help="pressure relaxation factors, each in (0, 1]")
    parser.add_argument("--alpha-t", type=relaxation_factor, nargs="+", default=None, metavar="T",
                        help="k/omega relaxation factors, each in (0, 1]: a 3-D grid (default: k/omega "
                        "fixed, see --relax-k-omega)")
    parser.add_argument("--mesh-scale", type=positive_float, default=1.0,
                        help=f"mesh resolution factor (1.0 = 20,540 cells; default 1.0). Use >= "
                        f"{MESH_SCALE_USABLE_MIN:g}: coarser meshes diverge with the factors that are best "
                        "on the full mesh, a different control problem")
    parser.add_argument("--step-height", type=positive_float, nargs="+", default=[STEP_HEIGHT_H], metavar="M",
                        help=f"step heights in m of the built-in case (default {STEP_HEIGHT_H:g} = h; "
                        f"{2 * STEP_HEIGHT_H:g} = 2h, the paper's second test geometry); several: every "
                        "cell on every (height, velocity)")
    parser.add_argument("--pool", type=positive_int, default=1, help="worker processes (default 1)")
    parser.add_argument("--simple-variant", choices=("SIMPLE", "SIMPLEC"), default=None,
                        help="pressure-velocity coupling (default: SIMPLEC, the paper's code's)")
    parser.add_argument("--inlet-velocity", type=positive_float, nargs="+", default=[44.2], metavar="V",
                        help="inlet velocities in m/s (default 44.2, the paper's U_ref); several: every cell "
                        "on every (height, velocity), and OUT/family_best.json")
    parser.add_argument("--max-iterations", type=positive_int, default=4000,
                        help="iteration cap per cell (default 4000)")
    parser.add_argument("--relax-k-omega", type=k_omega_factor, default=None, metavar="F",
                        help=f"relaxation factor of k and omega, in (0, 1], or {FOLLOW_ALPHA_U!r} to follow "
                        f"alpha_u (default: {BUILTIN_RELAX_K_OMEGA:g}, the paper's code's)")
    parser.add_argument("--criterion", choices=CRITERIA, default="train",
                        help="convergence criterion: the paper's train (1e-3) or test (5e-4) thresholds")
    add_confirm_argument(parser)
    parser.add_argument("--out", required=True, help="output directory (created if missing)")
    parser.set_defaults(func=run_grid_foam)


def _config(args: argparse.Namespace) -> Any:
    convergence = TRAIN_CONVERGENCE if args.criterion == "train" else TEST_CONVERGENCE
    if args.alpha_t is not None and args.relax_k_omega is not None:
        fail("--alpha-t and --relax-k-omega both set the k/omega factor: give one")
    for flag, values in (("--step-height", args.step_height), ("--inlet-velocity", args.inlet_velocity)):
        if len({f"{v:g}" for v in values}) != len(values):
            fail(f"{flag}: the values must be distinct, got {' '.join(f'{v:g}' for v in values)}")
    cfg = FoamEnvConfig(mesh_scale=args.mesh_scale, step_height=args.step_height[0],
                        simple_variant=args.simple_variant,
                        inlet_velocity=args.inlet_velocity[0], max_iterations=args.max_iterations,
                        relax_k_omega=args.relax_k_omega, convergence=dict(convergence),
                        confirm_alpha_u=args.confirm_alpha_u)
    try:
        for height, velocity in _conditions(args):  # each condition must be a case the env accepts
            dataclasses.replace(cfg, step_height=height, inlet_velocity=velocity).validate()
        return cfg.validate()
    except ValueError as err:
        fail(str(err))


def _conditions(args: argparse.Namespace) -> list[tuple[float, float]]:
    """Every (step height, inlet velocity) of the grid, heights outermost."""
    return [(h, v) for h in args.step_height for v in args.inlet_velocity]


def _check_openfoam() -> None:
    try:
        find_openfoam()
    except OpenFOAMNotFoundError as err:
        fail(str(err))


def _check_out_dir(text: str) -> Path:
    out = Path(text)
    if out.exists() and not out.is_dir():
        fail(f"--out {text}: exists and is not a directory")
    return out


def _make_out_dir(out: Path) -> Path:
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        fail(f"--out {out}: cannot create it ({err.strerror})")
    return out


def run_grid_foam(args: argparse.Namespace) -> int:
    """Run the grid, write grid.csv and the heatmaps (and family_best.json over several conditions),
    print the best cell. grid.csv is rewritten (atomically) after every finished cell, so a grid that is
    interrupted or killed keeps the runs it finished."""
    cfg = _config(args)
    out = _check_out_dir(args.out)
    _check_openfoam()
    _make_out_dir(out)
    conditions = _conditions(args)
    total = len(args.alpha_u) * len(args.alpha_p) * len(args.alpha_t or [None]) * len(conditions)
    finished: list[Any] = []
    with RunProgress("grid-foam") as progress:
        def on_cell(cell: Any) -> None:
            finished.append(cell)
            write_grid_csv(finished, out / "grid.csv")  # in finishing order until the grid is complete
            factors = ", ".join(f"{f:g}" for f in cell.factors)
            where = f"H {cell.step_height:g} m, V {cell.inlet_velocity:g}: " if len(conditions) > 1 else ""
            progress.step(f"{where}({factors}) {cell.outcome} @ {cell.iterations}", len(finished), total)

        try:
            cells = run_grid(cfg, args.alpha_u, args.alpha_p, pool=args.pool, on_cell=on_cell,
                             alpha_t=args.alpha_t, conditions=conditions if len(conditions) > 1 else None)
        except ValueError as err:  # a case the env rejects: the same for every cell
            fail(str(err))
        except KeyboardInterrupt:  # Ctrl-C or SIGTERM: run_grid's pool has stopped every solver
            kept = f"{out / 'grid.csv'} holds them" if finished else "nothing was written"
            progress.say(f"stopped: {len(finished)} of {total} cells finished ({kept})")
            raise
    write_grid_csv(cells, out / "grid.csv")  # grid order
    figures = _plot_conditions(cells, cfg, args, out)
    lines = [_best_line(cells)] if len(conditions) == 1 else _write_family_best(cells, args, out)
    written = ", ".join(str(out / f) for f in figures)
    progress.say("\n".join(lines) + f"\nwrote {out / 'grid.csv'} and {written}")
    return 0


def _plot_conditions(cells: list[Any], cfg: Any, args: argparse.Namespace, out: Path) -> list[str]:
    """The heatmaps: grid.png (grid_alpha_t_<A>.png) for one condition, else the same per condition
    with the stem grid_<geometry>_V<v>; returns the file names."""
    factor = cfg.k_omega_relaxation
    k_omega = ("" if args.alpha_t else "k/omega follow alpha_u, " if isinstance(factor, str)
               else f"k/omega {factor:g}, ")
    several = len(_conditions(args)) > 1
    names = []
    for height, velocity in conditions(cells):
        mine = [c for c in cells if c.condition == (height, velocity)]
        shape = f"{geometry_name(height)} (step {height:g} m), " if several else ""
        title = (f"SIMPLE iterations to convergence, constant factors\n{cfg.variant}, {k_omega}"
                 f"{args.criterion} criterion, mesh scale {args.mesh_scale:g}, {shape}V = {velocity:g} m/s")
        stem = f"grid_{geometry_name(height)}_V{velocity:g}" if several else "grid"
        if args.alpha_t:
            names += plot_grid_slices(mine, out, title, stem)
        else:
            plot_grid(mine, out / f"{stem}.png", title)
            names.append(f"{stem}.png")
    return names


def _best_line(cells: list[Any]) -> str:
    best = best_cell(cells)
    names = ("alpha_u", "alpha_p", "alpha_t")
    return ("best: " + " ".join(f"{n}={f:g}" for n, f in zip(names, best.factors, strict=False))
            + f" -> {best.iterations} iterations" if best else "no cell converged")


def _write_family_best(cells: list[Any], args: argparse.Namespace, out: Path) -> list[str]:
    """OUT/family_best.json (atomically); returns the summary line and the file's line."""
    best = family_best(cells, args.max_iterations)
    atomic_write_json(out / FAMILY_BEST_JSON, family_best_json(best, cells, args.max_iterations,
                                                               "--max-iterations of grid-foam"))
    return [summary_line(best, len(_conditions(args))), f"wrote {out / FAMILY_BEST_JSON}"]
