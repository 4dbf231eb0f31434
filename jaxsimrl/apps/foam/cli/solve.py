"""``jaxsimrl solve CASE``: converge a user's simpleFoam case with a trained controller
(jaxsimrl.apps.foam.solve).

    jaxsimrl solve my_case --out my_case.solved --compare

Writes OUT: the case converged (a normal OpenFOAM case), solve.json, solve.png. Bad input (no such case,
a decomposed case without --np of its count, no mpirun for --np, a case the bridge cannot drive, a non-empty
--out, a bad --policy, OpenFOAM missing) is one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import Any

from foam_bridge import DEFAULT_TOLERANCE, CaseError, OpenFOAMNotFoundError
from jaxsimrl.apps.foam.cli.grid_foam import check_factor, relaxation_factor
from jaxsimrl.apps.foam.cli.solve_campaign import add_campaign_arguments, is_campaign, run_campaign_command
from jaxsimrl.apps.foam.solve import solve_case
from jaxsimrl.apps.foam.solve.controller import DEFAULT_CONTROLLER
from jaxsimrl.apps.foam.solve.criterion import parse_residual
from jaxsimrl.apps.foam.solve.rules import DEFAULT_RULE
from jaxsimrl.cli.errors import fail, positive_float, positive_int


def register(subparsers: Any) -> None:
    """Add the ``solve`` subcommand."""
    parser = subparsers.add_parser(
        "solve", help="converge an OpenFOAM simpleFoam case: its own settings, or a controller",
        description="Copy CASE to --out and run it to convergence, with a report (solve.json, solve.png) "
        "and, with --compare, a measure of how far its answer may move. By default with the case's own "
        "settings: the iterations, solver time and answer of your own run, never more (measured on 26 cases "
        "of three sets: 1.000x own iterations on every one; docs/solve.md). --controller or --policy sets "
        "the factors instead, at the risk measured there; a watchdog hands a stalling or growing run to the "
        "case's own factors, and a failed run is replaced by the case's own run. Convergence is the case's "
        "residualControl (or --residual), confirmed for a controller's run at a fixed relaxation, or the "
        "case's own function objects ending the run (runTimeControl).")
    parser.add_argument("case", metavar="CASE", type=Path, nargs="+",
                        help="a simpleFoam case directory (never modified); several, or a directory holding "
                        "cases: a campaign (below)")
    parser.add_argument("--out", type=Path, metavar="DIR", help="output directory, new or empty "
                        "(default: ./NAME.solved, NAME the case directory's name)")
    parser.add_argument("--policy", metavar="RUN_DIR", help="a train-foam run directory (default: the "
                        "shipped controller)")
    parser.add_argument("--controller", choices=("own", "learned", "residual-rule", "bandit", "random",
                                                 "guarded"), default=None,
                        help="own (default): the case's own factors, so never more iterations than your own "
                        "run and the same answer (no controller measured here is safe on every case: "
                        "docs/solve.md). Opt-in, each faster on some cases and slower on others: learned: "
                        "the shipped controller or --policy (SIMPLEC cases with an inlet); residual-rule "
                        "raises the factors while the residuals fall and goes back when they grow; bandit "
                        "tries factors from the case's own to its box's top and plays the one that gains "
                        "most; guarded raises them half-way for the start-up descent and hands the rest to "
                        "the case's own; random draws them in the box at every step (a baseline)")
    parser.add_argument("--solves", choices=("own", "lean"), default="own",
                        help="the controlled run's linear solves: the case's own (default), or lean (the "
                        "pressure solve's relTol at least 0.3, every other field's at least 0.1: the same "
                        "answer, less work per iteration, but more iterations on some cases)")
    parser.add_argument("--compare", action="store_true", help="also run the case with its own settings, "
                        "in parallel, and report the savings; and a third run at its own factors with "
                        "alpha_u 0.05 off, to measure how far two legitimate runs end apart at its criterion "
                        "(the spread): the answers agree when within the larger of the tolerance and the "
                        "spread")
    parser.add_argument("--no-spread", action="store_false", dest="spread",
                        help="with --compare: skip the spread run (the agreement then uses the tolerance "
                        "alone)")
    parser.add_argument("--compare-constant", type=relaxation_factor, nargs="+", metavar="F",
                        help="also run the case with constant factors U P [TURBULENCE]")
    parser.add_argument("--residual", type=residual_spec, metavar="SPEC",
                        help="the convergence criterion instead of the case's SIMPLE residualControl (needed "
                        "when it has none): 1e-4 for every solved field, or p=1e-3,U=1e-4 for those fields; "
                        "used by the --compare runs too and written into --out's fvSolution")
    parser.add_argument("--from-time", type=time_value, metavar="T", dest="from_time",
                        help="the case's time directory to start from (default: its latest, as startFrom "
                        "latestTime: a partly converged run goes on from its fields; 0 starts over)")
    parser.add_argument("--max-iterations", type=positive_int, metavar="N",
                        help="iteration budget (default: the case's controlDict endTime minus the start "
                        "time, / deltaT)")
    parser.add_argument("--confirm-alpha-u", type=check_factor, default=None, metavar="A",
                        dest="confirm_alpha_u", help="the convergence check relaxation cannot move: one "
                        "SIMPLE iteration at alpha_u = A from the converged fields (default: the case's own "
                        "alpha_u, 0.9 if it does not relax U)")
    parser.add_argument("--step-timeout", type=positive_float, default=300.0, metavar="S",
                        help="watchdog on the solver: seconds one step of 100 iterations may take "
                        "(default 300)")
    parser.add_argument("--inlet-patch", default=None, metavar="NAME",
                        help="the patch whose mean |U|^2 the controller observes (default: the case's "
                             "'inlet'; a case without one runs under a rule or its own settings)")
    parser.add_argument("--np", type=positive_int, default=None, metavar="N", dest="ranks",
                        help="run every simpleFoam of the solve on N MPI ranks (mpirun -np N simpleFoam "
                        "-parallel): the case is decomposed with its decomposeParDict when that asks for N "
                        "subdomains, else into N slabs (method simple); a decomposed CASE needs its own N. "
                        "OUT holds the case reconstructed; 1: serial")
    parser.add_argument("--keep-decomposed", action="store_true",
                        help="with --np: also leave the ranks' processor* directories in OUT")
    parser.add_argument("--settle", type=settle_tolerance, default=DEFAULT_TOLERANCE, metavar="TOL",
                        help="stop the case's own run once its answer has settled: every solved field and "
                        "every value of the case's function objects within TOL (a relative error) of "
                        "where the run would settle, as estimated from its history, or oscillating about "
                        f"a mean that no longer moves (default {DEFAULT_TOLERANCE:g}; 'off': the plain "
                        "run, ended only by its criterion, its function objects or its budget). Never more "
                        "iterations than your own run; where it stops sooner, the answer is within TOL of "
                        "where that run would settle (docs/solve.md); the monitor costs a little solver "
                        "time on top. Exit code 0 for converged or settled, 1 for oscillating or out of "
                        "budget")
    parser.add_argument("--quiet", action="store_true", help="print only the summary")
    add_campaign_arguments(parser)
    parser.set_defaults(func=run_solve)


def residual_spec(text: str) -> Any:
    """argparse type of --residual (jaxsimrl.apps.foam.solve.criterion.parse_residual)."""
    try:
        return parse_residual(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def settle_tolerance(text: str) -> float | None:
    """argparse type of --settle: a relative tolerance in (0, 1), or "off" (None)."""
    if text.strip().lower() == "off":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a tolerance in (0, 1) or 'off', got {text!r}") from None
    if not 0 < value < 1:
        raise argparse.ArgumentTypeError(f"expected a tolerance in (0, 1) or 'off', got {text!r}")
    return value


def time_value(text: str) -> float:
    """argparse type of --from-time: a time >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a time >= 0, got {text!r}") from None
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a time >= 0, got {text!r}")
    return value


def compilation_cache() -> None:
    """Turn on JAX's persistent compilation cache (``$XDG_CACHE_HOME/jaxsimrl/xla``, else
    ``~/.cache/jaxsimrl/xla``) for this process, unless the user set JAX_COMPILATION_CACHE_DIR: compiling
    the controller's first action takes 0.7 s (seconds on a loaded machine) of every solve's fixed cost,
    and a cached compilation is read back in a fraction of that. The computation is the same; only where
    its machine code comes from changes. JAX reads these variables when it is imported (in the
    controller's loading thread), so this runs before."""
    if "JAX_COMPILATION_CACHE_DIR" in os.environ or "jax" in sys.modules:
        return
    try:
        cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "jaxsimrl" / "xla"
    except RuntimeError:  # no home directory: compile every time, as before
        return
    os.environ["JAX_COMPILATION_CACHE_DIR"] = str(cache)
    os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")  # default 1 s: ours are less


def solve_options(args: argparse.Namespace) -> dict[str, Any]:
    """solve_case's keyword arguments from the command line (but the case, out and say)."""
    shipped = str(DEFAULT_CONTROLLER) if args.controller == "learned" and args.policy is None else None
    return {"policy": args.policy or shipped, "compare": args.compare,
            "compare_constant": args.compare_constant,
            "max_iterations": args.max_iterations, "confirm_alpha_u": args.confirm_alpha_u or "own",
            "step_timeout_s": args.step_timeout, "inlet_patch": args.inlet_patch, "residual": args.residual,
            "from_time": args.from_time, "rule": rule_of(args),
            "ranks": args.ranks, "keep_decomposed": args.keep_decomposed, "spread": args.spread,
            "solves": args.solves, "settle": args.settle}


def rule_of(args: argparse.Namespace) -> str | None:
    """The rule solve runs: --controller's; the default (the case's own factors) when neither it nor
    --policy is given; None for a learned controller (--policy, or the shipped one)."""
    if args.controller == "learned" or (args.controller is None and args.policy is not None):
        return None
    return args.controller or DEFAULT_RULE


def run_solve(args: argparse.Namespace) -> int:
    """Run solve_case and print its summary (a campaign: jaxsimrl.apps.foam.cli.solve_campaign)."""
    if args.policy is not None and args.controller not in (None, "learned"):
        fail(f"--policy is a learned controller; --controller {args.controller} needs no policy")
    if args.keep_decomposed and (args.ranks or 1) < 2:
        fail("--keep-decomposed needs --np N with N >= 2")
    if args.compare_constant is not None and len(args.compare_constant) not in (2, 3):
        fail(f"--compare-constant takes 2 or 3 factors (U P [TURBULENCE]), got {len(args.compare_constant)}")
    compilation_cache()
    if is_campaign(args):
        return run_campaign_command(args, solve_options(args))
    (args.case,) = args.case
    out = args.out if args.out is not None else Path.cwd() / f"{Path(args.case).resolve().name}.solved"
    say = (lambda text: None) if args.quiet else (lambda text: print(text, flush=True))
    try:
        report = solve_case(args.case, out, say=say, **solve_options(args))
    except (ValueError, CaseError, OpenFOAMNotFoundError) as err:
        fail(" ".join(str(err).split()))
    print(report.summary())
    print(f"wrote {out} (the case, log.simpleFoam, solve.json, solve.png)")
    args.skip_teardown = True  # jaxsimrl.cli.main.entry
    return 0 if report.succeeded else 1
