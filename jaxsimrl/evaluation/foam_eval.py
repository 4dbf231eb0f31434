"""eval-foam: a train-foam policy against baselines under the paper's test protocol.

The protocol (Pawar & Maulik, "Solver convergence acceleration", test): inlet velocities 25, 50 and
75 m/s (25 and 75 lie outside the training range), the test criterion (TEST_CONVERGENCE), step heights
h and 2h, the full mesh. Every other case setting (SIMPLE variant, k/omega relaxation, interval,
action box, residual features, iteration cap, ...) is the training run's own.

Controllers, all in the same run (see foam_controllers):

- ``learned_deterministic``: the policy's mean action; one run per (geometry, velocity): the solver is
  deterministic, so repeats would be identical;
- ``learned_stochastic``: actions sampled from the policy, ``samples`` runs (the paper: 10);
- ``best_constant``: the converged cell with the fewest iterations of a grid-foam grid.csv (of a grid
  over several conditions: the cell best for that family, jaxsimrl.evaluation.family), or of a small
  grid eval-foam runs itself at the first velocity on the first geometry; one run per cell;
- ``tutorial_defaults``: the tutorial's (U 0.9, p 0.8, and on a run with the k/omega action k/omega
  0.8, backwardFacingStep2D's ".*" 0.8; a 2-action run keeps its own k/omega factor); one run;
- ``random``: factors uniform in the action box at every step, ``samples`` runs (the paper's baseline);
- ``case_oracle`` (only when asked for: it costs a grid per case): the best constant of a grid on each
  test case itself, and what that grid cost (foam_oracle).

With ``reference_iterations`` N, every (geometry, velocity) first gets a reference run: the best
constant (the tutorial's defaults without one) for exactly N iterations, with no convergence test.
Every run then reports ``u_error``, the relative L2 distance of the U field it ended with from that
reference (foam_bridge.fields says why iterations alone can mislead). With ``reference_cache`` the
references are reused from (and stored in) a directory (foam_reference_cache).

Every episode's uid is a hash of (controller, geometry, velocity, sample); it seeds the episode's
random actions, so the same command gives the same numbers, and an episode stays the same when other
velocities, geometries or samples are added to the command. :func:`evaluate_foam` writes
``eval.json``, ``eval.csv`` and the figures (foam_plots) into the output directory and returns the
report.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import time
import zlib
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from foam_bridge.config import (
    BUILTIN_RELAX_K_OMEGA,
    STEP_HEIGHT_H,
    TEST_CONVERGENCE,
    FoamEnvConfig,
    without_convergence_test,
)
from jaxsimrl.evaluation import foam_oracle
from jaxsimrl.evaluation.foam_controllers import (
    CaseGridController,
    ConstantController,
    LearnedController,
    RandomController,
)
from jaxsimrl.evaluation.foam_reference_cache import CachedReference, ReferenceCache, reference_keys
from jaxsimrl.evaluation.foam_runner import EpisodeResult, Job, run_episodes
from jaxsimrl.runs.atomic import atomic_write_json, atomic_write_text

EVAL_DIR = "eval"
EVAL_JSON = "eval.json"
EVAL_CSV = "eval.csv"
GRID_CSV = "baseline_grid.csv"
GRID_PNG = "baseline_grid.png"
DEFAULT_VELOCITIES = (25.0, 50.0, 75.0)
DEFAULT_STEP_HEIGHTS = (STEP_HEIGHT_H, 2 * STEP_HEIGHT_H)
#: The grid eval-foam runs for the best constant when no --baseline-grid is given (both axes).
DEFAULT_GRID = (0.8, 0.9, 0.95)
#: backwardFacingStep2D's own relaxation factors (U 0.9, p 0.8; k and omega as the case sets them).
TUTORIAL_DEFAULTS = (0.9, 0.8)
#: Controller keys, in the order of tables and figures.
CONTROLLERS = ("learned_deterministic", "learned_stochastic", "best_constant", "tutorial_defaults", "random",
               foam_oracle.ORACLE)
#: Those run without --controllers: the oracle's grid per case is paid for only when asked.
DEFAULT_CONTROLLERS = CONTROLLERS[:-1]
#: FoamEnvConfig fields left out of the report's "case": they vary per cell, or the report gives them
#: apart ("action_box": the training box; the env's own box is widened to hold the constants).
CASE_OMITTED = ("work_dir", "keep_cases", "step_height", "inlet_velocity", "action_low", "action_high")
CSV_COLUMNS = ("controller", "geometry", "step_height", "velocity", "sample", "outcome", "cause",
               "iterations", "wall_time_s", "cpu_time_s", "linear_iterations", "p_linear_iterations",
               "u_error", "failed_checks", "steps", "actions")
#: Controller name of the reference runs (not a controller of the protocol: no row in the tables).
REFERENCE = "reference"


@dataclass(frozen=True)
class EvalSpec:
    """What to evaluate and how; ``step_heights=None`` -> h and 2h (a user's case: its own geometry)."""

    run_dir: Path
    velocities: tuple[float, ...] = DEFAULT_VELOCITIES
    step_heights: tuple[float, ...] | None = None
    mesh_scale: float = 1.0
    samples: int = 10
    pool: int = 1
    seed: int = 0
    baseline_grid: Path | None = None
    grid_alpha_u: tuple[float, ...] = DEFAULT_GRID
    grid_alpha_p: tuple[float, ...] = DEFAULT_GRID
    #: alpha_t of that grid for a run with the k/omega action (None: the paper's 0.8 only).
    grid_alpha_t: tuple[float, ...] | None = None
    out: Path | None = None
    controllers: tuple[str, ...] = DEFAULT_CONTROLLERS
    reference_iterations: int | None = None
    #: A directory of reference runs to reuse and add to (foam_reference_cache); None: run them all.
    reference_cache: Path | None = None
    #: FoamEnvConfig.confirm_alpha_u of every run (None: the training config's own, the paper's test).
    confirm_alpha_u: float | None = None
    #: Axes of the per-case oracle's grid (None: --baseline-grid's, else the small grid's; foam_oracle).
    oracle_alpha_u: tuple[float, ...] | None = None
    oracle_alpha_p: tuple[float, ...] | None = None
    oracle_alpha_t: tuple[float, ...] | None = None

    def validate(self) -> EvalSpec:
        """One-line ValueError naming the first bad field; returns self."""
        _positive("velocities", self.velocities)
        if self.step_heights is not None:
            _positive("step_heights", self.step_heights)
            _distinct("step_heights", [geometry_name(h) for h in self.step_heights])
        _distinct("velocities", [f"{v:g}" for v in self.velocities])
        _positive("mesh_scale", (self.mesh_scale,))
        unknown = [c for c in self.controllers if c not in CONTROLLERS]
        if not self.controllers or unknown:
            raise ValueError(f"controllers must be some of {', '.join(CONTROLLERS)}, got "
                             f"{list(self.controllers)}")
        _distinct("controllers", self.controllers)
        if self.confirm_alpha_u is not None and not 0 < self.confirm_alpha_u < 1:
            raise ValueError(f"confirm_alpha_u must be a relaxation factor in (0, 1), "
                             f"got {self.confirm_alpha_u!r}")
        if self.reference_cache is not None:
            if self.reference_iterations is None:
                raise ValueError("reference_cache needs reference_iterations (there are no references to "
                                 "cache without it)")
            if Path(self.reference_cache).exists() and not Path(self.reference_cache).is_dir():
                raise ValueError(f"reference_cache {self.reference_cache}: exists and is not a directory")
        optional = ("reference_iterations",) if self.reference_iterations is not None else ()
        for name in ("samples", "pool", *optional):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        given = [n for n in ("grid_alpha_t", "oracle_alpha_u", "oracle_alpha_p", "oracle_alpha_t")
                 if getattr(self, n) is not None]
        if any(n.startswith("oracle") for n in given) and foam_oracle.ORACLE not in self.controllers:
            raise ValueError(f"oracle_alpha_u/p/t set the grid of the {foam_oracle.ORACLE} controller: add "
                             "it to the controllers, or leave them out")
        for name in ("grid_alpha_u", "grid_alpha_p", *given):
            values = getattr(self, name)
            if not values or not all(math.isfinite(v) and 0 < v <= 1 for v in values):
                raise ValueError(f"{name}: relaxation factors must be in (0, 1], got {list(values)}")
        return self

    @property
    def output_dir(self) -> Path:
        return Path(self.out) if self.out is not None else Path(self.run_dir) / EVAL_DIR


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


def _positive(name: str, values: Sequence[float]) -> None:
    if not values or not all(isinstance(v, int | float) and math.isfinite(v) and v > 0 for v in values):
        raise ValueError(f"{name} must be numbers > 0, got {list(values)}")


def _distinct(name: str, labels: Sequence[str]) -> None:
    if len(set(labels)) != len(labels):
        raise ValueError(f"{name} must be distinct, got {list(labels)}")


def geometry_name(step_height: float | None) -> str:
    """"h", "2h", "1.5h" for the built-in case's step heights; "case" for a user's case (None)."""
    if step_height is None:
        return "case"
    ratio = step_height / STEP_HEIGHT_H
    return "h" if math.isclose(ratio, 1.0) else f"{ratio:.4g}h"


def geometries(spec: EvalSpec, train: FoamEnvConfig) -> dict[str, float | None]:
    """Geometry name -> step height (None: a user's case, whose geometry is its own)."""
    if train.case_dir is not None:
        if spec.step_heights is not None:
            raise ValueError("step heights apply to the built-in case only; this run trained on "
                             f"{train.case_dir}")
        return {"case": None}
    heights = DEFAULT_STEP_HEIGHTS if spec.step_heights is None else spec.step_heights
    return {geometry_name(h): float(h) for h in heights}


def eval_config(train: FoamEnvConfig, spec: EvalSpec, step_height: float | None,
                constants: Sequence[tuple[float, float]]) -> FoamEnvConfig:
    """The training config under the test protocol: test criterion (checked at the spec's
    confirm_alpha_u, if it has one), this geometry and the spec's mesh; its action box widened to hold
    the constant factors (they must not be clipped; learned and random actions lie in the training box
    anyway)."""
    from foam_bridge.grid import grid_config

    cfg = dataclasses.replace(train, mesh_scale=spec.mesh_scale, convergence=dict(TEST_CONVERGENCE),
                              work_dir=None, keep_cases=False)
    if spec.confirm_alpha_u is not None:
        cfg = dataclasses.replace(cfg, confirm_alpha_u=spec.confirm_alpha_u)
    if step_height is not None:
        cfg = dataclasses.replace(cfg, step_height=step_height)
    third = [c[2] for c in constants] if cfg.action_size == 3 else None
    return grid_config(cfg, [c[0] for c in constants], [c[1] for c in constants], third)


def read_baseline_grid(path: str | Path) -> list[Any]:
    """The cells of a grid-foam grid.csv; one-line ValueError for a missing or bad file."""
    from foam_bridge.grid import read_grid_csv

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
    cell, or over several conditions the cell best for the family (jaxsimrl.evaluation.family, each
    failure at the grid's cap); one-line ValueError for a missing or bad file or no converged cell."""
    from foam_bridge.grid import best_cell
    from jaxsimrl.evaluation.family import conditions, family_best, family_best_json, grid_cap

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
    from foam_bridge.grid import best_cell, plot_grid, run_grid, write_grid_csv

    def on_cell(cell: Any) -> None:
        say(f"grid {_text(cell.factors)}: {cell.outcome} @ {cell.iterations} it")

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


def _text(factors: Sequence[float]) -> str:
    return "(" + ", ".join(f"{f:g}" for f in factors) + ")"


def episode_uid(controller: str, geometry: str, velocity: float, sample: int) -> int:
    """A stable 31-bit id of one episode of the protocol (it seeds the episode)."""
    return zlib.crc32(f"{controller}/{geometry}/{velocity:g}/{sample}".encode()) & 0x7FFFFFFF


def plan(names: Sequence[str], velocities: Sequence[float], repeats: dict[str, bool],
         samples: int, runs: dict[str, int] | None = None) -> list[Job]:
    """Every episode of the evaluation, geometry by geometry, velocity by velocity, for the controllers
    of ``repeats`` (in CONTROLLERS order): ``samples`` runs per cell of those that repeat, one of the
    others, and ``runs[name]`` of those named there (the oracle: one per cell of its grid)."""
    runs = runs or {}
    jobs: list[Job] = []
    for geometry in names:
        for velocity in velocities:
            for controller in (c for c in CONTROLLERS if c in repeats):
                count = runs.get(controller, samples if repeats[controller] else 1)
                for sample in range(count):
                    uid = episode_uid(controller, geometry, velocity, sample)
                    jobs.append(Job(uid, controller, geometry, float(velocity), sample))
    if len({job.uid for job in jobs}) != len(jobs):  # a crc32 collision: never seen, but never silent
        raise ValueError("two episodes of the plan got the same uid; change a velocity slightly")
    return jobs


def make_controllers(run: Any, baseline: Baseline | None, pool: int, seed: int,
                     names: Sequence[str] = DEFAULT_CONTROLLERS,
                     oracle: Sequence[Sequence[float]] = ()) -> dict[str, Any]:
    """The controllers ``names`` of the protocol (CONTROLLERS; "best_constant" needs a baseline,
    "case_oracle" the cells of its grid, ``oracle``)."""
    from jaxsimrl.policy import BatchActor  # JAX, only once learned controllers are built

    actor = BatchActor(run.policy, pool)
    makers = {
        "learned_deterministic": lambda: LearnedController("learned_deterministic", actor, True, seed),
        "learned_stochastic": lambda: LearnedController("learned_stochastic", actor, False, seed),
        "best_constant": lambda: ConstantController("best_constant", as_action(run.foam, baseline.factors)),
        "tutorial_defaults": lambda: ConstantController("tutorial_defaults",
                                                        as_action(run.foam, TUTORIAL_DEFAULTS)),
        "random": lambda: RandomController("random", run.foam.action_low, run.foam.action_high, seed),
        foam_oracle.ORACLE: lambda: CaseGridController(foam_oracle.ORACLE,
                                                       [as_action(run.foam, c) for c in oracle]),
    }
    return {name: makers[name]() for name in names}


def constant_factors(baseline: Baseline | None, cfg: FoamEnvConfig,
                     oracle: Sequence[Sequence[float]] = ()) -> list[tuple[float, ...]]:
    """The constant controllers' actions, the oracle's grid cells included (the env's action box must
    hold them)."""
    chosen = [TUTORIAL_DEFAULTS] if baseline is None else [baseline.factors, TUTORIAL_DEFAULTS]
    return [as_action(cfg, factors) for factors in (*chosen, *oracle)]


def evaluate_foam(spec: EvalSpec, on_result: Callable[[EpisodeResult, int, int], None] | None = None,
                  say: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run the protocol on ``spec.run_dir``'s last checkpoint; write eval.json, eval.csv and the
    figures to ``spec.output_dir``; return the report. Bad input: one-line ValueError, before any
    solver starts."""
    from jaxsimrl.evaluation.foam_policy import load_foam_run  # JAX: keeps the CLI light until it runs

    say = say or (lambda text: None)
    spec.validate()
    run = load_foam_run(spec.run_dir)
    shapes = geometries(spec, run.foam)
    grid = read_baseline_grid(spec.baseline_grid) if spec.baseline_grid is not None else None
    baseline = baseline_from_csv(spec.baseline_grid, grid) if grid is not None else None
    oracle = foam_oracle.oracle_cells(foam_oracle.oracle_axes(spec, run.foam, grid)) \
        if foam_oracle.ORACLE in spec.controllers else []
    out = _make_output_dir(spec.output_dir)
    started = time.monotonic()
    if baseline is None and "best_constant" in spec.controllers:
        first = next(iter(shapes))
        say(f"no --baseline-grid: searching the best constant on a grid at V = {spec.velocities[0]:g} m/s, "
            f"{first}")
        grid_cfg = eval_config(run.foam, spec, shapes[first], constant_factors(None, run.foam))
        baseline = baseline_from_grid(spec, grid_cfg, spec.velocities[0], first, say)
    if baseline is not None:
        as_action(run.foam, baseline.factors)  # a 3-D grid's best cell for a 2-action policy: say so now
        say(f"best constant {_text(baseline.factors)} from {baseline.source}")
    controllers = make_controllers(run, baseline, spec.pool, spec.seed, spec.controllers, oracle)
    jobs = plan(list(shapes), spec.velocities, {k: c.repeats for k, c in controllers.items()}, spec.samples,
                {foam_oracle.ORACLE: len(oracle)})
    for job in (j for j in jobs if j.controller == foam_oracle.ORACLE):
        controllers[job.controller].assign(job.uid, job.sample)
    constants = constant_factors(baseline, run.foam, oracle)
    results, references = _run_plan(spec, run, shapes, jobs, controllers, baseline, constants, on_result)
    rows = [run_row(r, shapes[r.job.geometry], references.errors.get(r.job.uid)) for r in results]
    rows, chosen = foam_oracle.choose(rows, oracle, run.foam.max_iterations)
    report = build_report(spec, run, baseline, shapes, rows, time.monotonic() - started, references,
                          constants, chosen)
    write_outputs(report, rows, out)
    return report


def _run_plan(spec: EvalSpec, run: Any, shapes: dict[str, float | None], jobs: list[Job],
              controllers: dict[str, Any], baseline: Baseline | None, constants: list[tuple[float, ...]],
              on_result: Callable[[EpisodeResult, int, int], None] | None
              ) -> tuple[list[EpisodeResult], References]:
    """Every job, one geometry (one case, one pool) after the other, each geometry's reference runs
    first (with ``spec.reference_iterations``); results in plan order."""

    results: list[EpisodeResult] = []
    references = References(spec, baseline, run.foam)
    done, total = 0, len(jobs) + len(references.plan(shapes, spec.velocities))

    def progress(result: EpisodeResult) -> None:
        nonlocal done
        done += 1
        if on_result is not None:
            on_result(result, done, total)

    for name, height in shapes.items():
        cfg = eval_config(run.foam, spec, height, constants)
        if references.wanted:
            references.run(cfg, name, spec.velocities, spec.pool, progress)
        mine = [j for j in jobs if j.geometry == name]
        done_here = run_episodes(cfg, mine, controllers, spec.pool, progress, fields=references.wanted)
        results += [references.measure(r) for r in done_here]
    return results, references


class References:
    """The reference runs of an evaluation (none without ``spec.reference_iterations``) and the error
    of every run's final U field against its (geometry, velocity)'s reference."""

    def __init__(self, spec: EvalSpec, baseline: Baseline | None, cfg: FoamEnvConfig) -> None:

        self.iterations = spec.reference_iterations
        self.factors = as_action(cfg, baseline.factors if baseline is not None else TUTORIAL_DEFAULTS)
        self.cache = None if spec.reference_cache is None else ReferenceCache(spec.reference_cache)
        self.runs: dict[tuple[str, float], EpisodeResult] = {}
        self.final_residuals: dict[tuple[str, float], dict[str, float]] = {}
        self.cached: set[tuple[str, float]] = set()
        self.errors: dict[int, float | None] = {}

    @property
    def wanted(self) -> bool:
        return self.iterations is not None

    def plan(self, geometries: Sequence[str], velocities: Sequence[float]) -> list[Job]:
        if not self.wanted:
            return []
        return [Job(episode_uid(REFERENCE, g, v, 0), REFERENCE, g, float(v), 0)
                for g in geometries for v in velocities]

    def run(self, cfg: FoamEnvConfig, geometry: str, velocities: Sequence[float], pool: int,
            progress: Callable[[EpisodeResult], None]) -> None:

        long_run = dataclasses.replace(without_convergence_test(cfg), max_iterations=self.iterations)
        keys = {} if self.cache is None else reference_keys(long_run, velocities, self.factors)
        to_run = []
        for job in self.plan([geometry], velocities):
            entry = None if self.cache is None else self.cache.load(keys[job.velocity])
            if entry is None:
                to_run.append(job)
                continue
            result = EpisodeResult(job, entry.outcome, "", entry.iterations, 0.0, [], None, (), entry.final_u)
            self._keep(geometry, result, entry.final_residuals)
            self.cached.add((geometry, job.velocity))
            progress(result)
        controller = {REFERENCE: ConstantController(REFERENCE, self.factors)}
        for result in run_episodes(long_run, to_run, controller, pool, progress, fields=True):
            residuals = result.trace[-1].residuals if result.trace else {}
            self._keep(geometry, result, residuals)
            self._store(keys.get(result.job.velocity), geometry, result, residuals)

    def _keep(self, geometry: str, result: EpisodeResult, residuals: dict[str, float]) -> None:
        self.runs[(geometry, result.job.velocity)] = result
        self.final_residuals[(geometry, result.job.velocity)] = residuals

    def _store(self, key: str | None, geometry: str, result: EpisodeResult, residuals: dict[str, float]
               ) -> None:
        """Keep a reference that ran its iterations in the cache (not one that failed on the way)."""

        if key is None or result.outcome != "truncated" or result.iterations != self.iterations \
                or result.final_u is None:
            return
        about = {"geometry": geometry, "velocity": result.job.velocity, "factors": list(self.factors)}
        self.cache.store(key, CachedReference(result.outcome, result.iterations, residuals, result.final_u),
                         about)

    def measure(self, result: EpisodeResult) -> EpisodeResult:
        """Record the run's U error (None: no reference, or no final field); drop the field itself."""
        from foam_bridge.fields import relative_l2

        reference = self.runs.get((result.job.geometry, result.job.velocity))
        self.errors[result.job.uid] = relative_l2(result.final_u, None if reference is None
                                                  else reference.final_u)
        return dataclasses.replace(result, final_u=None)

    def summary(self) -> dict[str, Any] | None:
        """eval.json's "reference": how the references were run and how far each one got."""
        if not self.wanted:
            return None
        runs = {}
        for (geometry, velocity), result in self.runs.items():
            runs.setdefault(geometry, {})[f"{velocity:g}"] = {
                "outcome": result.outcome, "cause": result.cause, "iterations": result.iterations,
                "final_residuals": self.final_residuals[(geometry, velocity)],
                "has_field": result.final_u is not None, "cached": (geometry, velocity) in self.cached}
        return {"iterations": self.iterations, "factors": list(self.factors), "runs": runs,
                "cache": None if self.cache is None else str(self.cache.directory),
                "error": "relative L2 distance of a run's final U field from its reference's, all cells "
                         "and components, cells unweighted"}


def _make_output_dir(out: Path) -> Path:
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ValueError(f"--out {out}: cannot create it ({err.strerror})") from None
    return out


# ----- the report ------------------------------------------------------------------------------------
def run_row(result: EpisodeResult, step_height: float | None, u_error: float | None = None
            ) -> dict[str, Any]:
    """One run as a flat record (eval.csv's row; eval.json's per-run entry)."""
    cost = result.cost
    return {
        "controller": result.job.controller, "geometry": result.job.geometry, "step_height": step_height,
        "velocity": result.job.velocity, "sample": result.job.sample, "outcome": result.outcome,
        "cause": result.cause, "iterations": result.iterations, "wall_time_s": round(result.wall_time_s, 4),
        "cpu_time_s": None if cost is None else cost.cpu_time_s,
        "linear_iterations": None if cost is None else cost.total,
        "p_linear_iterations": None if cost is None else cost.of("p"),
        "u_error": u_error, "failed_checks": sum(not c["passed"] for c in result.confirmations),
        "steps": len(result.actions), "actions": result.actions,
    }


def stats(values: Sequence[float]) -> dict[str, float | int | None]:
    """n, mean, std (population), min and max; None entries for an empty list."""
    values = [float(v) for v in values if v is not None]
    if not values:
        return {"n": 0, "mean": None, "std": None, "min": None, "max": None}
    mean = sum(values) / len(values)
    std = math.sqrt(sum((v - mean) ** 2 for v in values) / len(values))
    return {"n": len(values), "mean": mean, "std": std, "min": min(values), "max": max(values)}


def cell_summary(rows: Sequence[dict[str, Any]], max_iterations: int) -> dict[str, Any]:
    """Statistics of one (controller, geometry, velocity) cell.

    ``iterations``, ``wall_time_s``, ``cpu_time_s`` and the linear-solver counts are over the runs that
    converged; ``penalised_iterations`` counts every other run at ``max_iterations``, as the training
    reward does (the return of a failed or truncated episode is -max_iterations); ``failed_checks``:
    the convergence checks its runs failed (FoamEnvConfig.confirm_alpha_u).
    """
    converged = [r for r in rows if r["outcome"] == "converged"]
    summary: dict[str, Any] = {"runs": list(rows), "outcomes": dict(Counter(r["outcome"] for r in rows)),
                               "converged": len(converged)}
    for key in ("iterations", "wall_time_s", "cpu_time_s", "linear_iterations", "p_linear_iterations",
                "u_error"):
        summary[key] = stats([r[key] for r in converged])
    summary["failed_checks"] = sum(r["failed_checks"] for r in rows)
    summary["penalised_iterations"] = stats(
        [r["iterations"] if r["outcome"] == "converged" else max_iterations for r in rows])
    return summary


def build_report(spec: EvalSpec, run: Any, baseline: Baseline | None, shapes: dict[str, float | None],
                 rows: Sequence[dict[str, Any]], wall_time_s: float,
                 references: References | None = None, constants: list[tuple[float, ...]] | None = None,
                 oracle: dict[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """eval.json: the protocol, the baseline, and per controller -> geometry -> velocity the runs
    (``rows``, as run_row makes them) and their statistics; the oracle's cells add its choice and cost
    (``oracle``, from foam_oracle.choose)."""
    from jaxsimrl.envs.foam_config import foam_config_to_json

    chosen = [c for c in CONTROLLERS if c in spec.controllers]
    table: dict[str, Any] = {c: {g: {} for g in shapes} for c in chosen}
    for controller in chosen:
        for geometry in shapes:
            for velocity in spec.velocities:
                cell = [r for r in rows if r["controller"] == controller and r["geometry"] == geometry
                        and r["velocity"] == float(velocity)]
                table[controller][geometry][f"{velocity:g}"] = cell_summary(cell, run.foam.max_iterations)
                if controller == foam_oracle.ORACLE and oracle:
                    table[controller][geometry][f"{velocity:g}"]["oracle"] = oracle[geometry][f"{velocity:g}"]
    case = eval_config(run.foam, spec, None, constants or constant_factors(baseline, run.foam))
    described = {
        "learned_deterministic": "the policy's mean action, one run per cell",
        "learned_stochastic": f"actions sampled from the policy, {spec.samples} runs per cell",
        "best_constant": None if baseline is None else
        f"constant {_text(baseline.factors)}, one run per cell",
        "tutorial_defaults": f"constant {TUTORIAL_DEFAULTS} (U, p), k/omega as the case, one run per cell",
        "random": f"uniform in the action box at every step, {spec.samples} runs per cell",
        foam_oracle.ORACLE: "per cell, the best constant of a grid on that case (its run; the grid's cost "
        "in 'oracle', its other runs in eval.csv as case_oracle_grid)",
    }
    return {
        "run_dir": str(run.path), "checkpoint_step": run.checkpoint_step, "checkpoint_update": run.update,
        "seed": spec.seed, "samples": spec.samples, "pool": spec.pool,
        "velocities": [float(v) for v in spec.velocities], "geometries": shapes,
        "mesh_scale": spec.mesh_scale, "criterion": dict(TEST_CONVERGENCE),
        "case": {k: v for k, v in foam_config_to_json(case).items()
                 if k not in CASE_OMITTED},
        "controllers": {c: described[c] for c in chosen},
        "action_box": {"low": list(run.foam.action_low), "high": list(run.foam.action_high)},
        "baseline": None if baseline is None else {
            "alpha_u": baseline.alpha_u, "alpha_p": baseline.alpha_p, "source": baseline.source,
            "grid_iterations": baseline.grid_iterations,
            **({} if baseline.alpha_t is None else {"alpha_t": baseline.alpha_t}),
            **({} if baseline.family is None else {"family": baseline.family})},
        "reference": None if references is None else references.summary(),
        "results": table,
        "wall_time_s": wall_time_s,
    }


def write_outputs(report: dict[str, Any], rows: Sequence[dict[str, Any]], out: Path) -> None:
    """eval.json, eval.csv (``rows``, one per run) and the figures, each written atomically."""
    from jaxsimrl.evaluation import foam_plots

    atomic_write_json(out / EVAL_JSON, report)
    atomic_write_text(out / EVAL_CSV, _csv(rows))
    foam_plots.plot_all(report, out)


def _csv(rows: Sequence[dict[str, Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: json.dumps(v) if k == "actions" else ("" if v is None else v)
                         for k, v in row.items()})
    return buffer.getvalue()
