"""eval-foam: a train-foam policy against baselines under the paper's test protocol.

The protocol and its controllers: foam_eval_spec (EvalSpec); the constants: foam_baseline; the
reference runs: foam_references; eval.json, eval.csv and the figures: foam_report. This module plans
the episodes and runs them on foam_bridge's episode pool (foam_runner).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from foam_bridge import TEST_CONVERGENCE
from jaxsimrl.apps.foam.evaluation import oracle as foam_oracle
from jaxsimrl.apps.foam.evaluation.baseline import (
    Baseline,
    as_action,
    baseline_from_csv,
    baseline_from_grid,
    constant_factors,
    factors_text,
    read_baseline_grid,
)
from jaxsimrl.apps.foam.evaluation.controllers import (
    CaseGridController,
    ConstantController,
    LearnedController,
    RandomController,
    RuleController,
)
from jaxsimrl.apps.foam.evaluation.eval_spec import (
    CONTROLLERS,
    DEFAULT_CONTROLLERS,
    RULE_CONTROLLERS,
    TUTORIAL_DEFAULTS,
    EvalSpec,
    episode_uid,
    eval_config,
    geometries,
)
from jaxsimrl.apps.foam.evaluation.references import References
from jaxsimrl.apps.foam.evaluation.report import build_report, run_row, write_outputs
from jaxsimrl.apps.foam.evaluation.runner import EpisodeResult, Job, run_episodes
from jaxsimrl.apps.foam.solve.rules import INTERVALS


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
    for name, rule in RULE_CONTROLLERS.items():
        makers[name] = lambda name=name, rule=rule: RuleController(
            name, rule, dict(TEST_CONVERGENCE), as_action(run.foam, TUTORIAL_DEFAULTS),
            (run.foam.action_low, run.foam.action_high), run.foam.variant == "SIMPLEC")
    return {name: makers[name]() for name in names}


def evaluate_foam(spec: EvalSpec, on_result: Callable[[EpisodeResult, int, int], None] | None = None,
                  say: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run the protocol on ``spec.run_dir``'s last checkpoint; write eval.json, eval.csv and the
    figures to ``spec.output_dir``; return the report. Bad input: one-line ValueError, before any
    solver starts."""
    from jaxsimrl.apps.foam.evaluation.policy import load_foam_run  # JAX: keeps the CLI light until it runs

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
        say(f"best constant {factors_text(baseline.factors)} from {baseline.source}")
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
        for interval, mine in _by_interval([j for j in jobs if j.geometry == name], cfg.interval).items():
            stepped, wanted = dataclasses.replace(cfg, interval=interval), references.wanted
            done_here = run_episodes(stepped, mine, controllers, spec.pool, progress, fields=wanted)
            results += [references.measure(r) for r in done_here]
    return results, references


def _by_interval(jobs: list[Job], interval: int) -> dict[int, list[Job]]:
    """The jobs by the step length they run at: the rules' own (jaxsimrl.apps.foam.solve.rules.INTERVALS), the
    protocol's ``interval`` for the others (a pool steps all its episodes alike)."""
    groups: dict[int, list[Job]] = {}
    for job in jobs:
        rule = RULE_CONTROLLERS.get(job.controller)
        groups.setdefault(interval if rule is None else INTERVALS[rule], []).append(job)
    return groups


def _make_output_dir(out: Path) -> Path:
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a directory")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ValueError(f"--out {out}: cannot create it ({err.strerror})") from None
    return out
