"""eval-foam's report: one row per run (eval.csv), per-cell statistics and eval.json, the figures."""

from __future__ import annotations

import csv
import io
import json
import math
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from foam_bridge import TEST_CONVERGENCE
from jaxsimrl.apps.foam.config import foam_config_to_json
from jaxsimrl.apps.foam.evaluation import oracle as foam_oracle
from jaxsimrl.apps.foam.evaluation.baseline import Baseline, constant_factors, factors_text
from jaxsimrl.apps.foam.evaluation.eval_spec import (
    CONTROLLERS,
    EVAL_CSV,
    EVAL_JSON,
    TUTORIAL_DEFAULTS,
    EvalSpec,
    eval_config,
)
from jaxsimrl.apps.foam.evaluation.references import References
from jaxsimrl.apps.foam.evaluation.runner import EpisodeResult
from jaxsimrl.runs.atomic import atomic_write_json, atomic_write_text

#: FoamEnvConfig fields left out of the report's "case": they vary per cell, or the report gives them
#: apart ("action_box": the training box; the env's own box is widened to hold the constants).
CASE_OMITTED = ("work_dir", "keep_cases", "step_height", "inlet_velocity", "action_low", "action_high")
CSV_COLUMNS = ("controller", "geometry", "step_height", "velocity", "sample", "outcome", "cause",
               "iterations", "wall_time_s", "cpu_time_s", "linear_iterations", "p_linear_iterations",
               "u_error", "failed_checks", "steps", "actions")


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
        f"constant {factors_text(baseline.factors)}, one run per cell",
        "tutorial_defaults": f"constant {TUTORIAL_DEFAULTS} (U, p), k/omega as the case, one run per cell",
        "random": f"uniform in the action box at every step, {spec.samples} runs per cell",
        "residual_rule": "jaxsimrl solve's residual rule (no training) from the tutorial's defaults, one run "
        "per cell",
        "bandit": "jaxsimrl solve's bandit (no training) from the tutorial's defaults, one run per cell",
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
    from jaxsimrl.apps.foam.evaluation import plots as foam_plots

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
