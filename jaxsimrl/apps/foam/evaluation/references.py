"""eval-foam's reference runs: per (geometry, velocity) one long run at a constant, and every run's
final U field measured against it (foam_bridge._fields says why iterations alone can mislead)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from typing import Any

from foam_bridge import FoamEnvConfig, relative_l2, without_convergence_test
from jaxsimrl.apps.foam.evaluation.baseline import Baseline, as_action
from jaxsimrl.apps.foam.evaluation.controllers import ConstantController
from jaxsimrl.apps.foam.evaluation.eval_spec import REFERENCE, TUTORIAL_DEFAULTS, EvalSpec, episode_uid
from jaxsimrl.apps.foam.evaluation.reference_cache import CachedReference, ReferenceCache, reference_keys
from jaxsimrl.apps.foam.evaluation.runner import EpisodeResult, Job, run_episodes


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
