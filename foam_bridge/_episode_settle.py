"""An episode's stop on its answer (FoamEnvConfig.settle): the answer monitor of ``jaxsimrl solve``
(foam_bridge._answer_monitor) installed in the episode's case and asked after every step.

Internal to foam_bridge (its users set FoamEnvConfig.settle); names here may change.

One monitor, one estimator, one verdict for solve, the env and campaigns: a controller can then be trained
and judged on cases whose criterion is never met, its episodes ending where their answer has settled (or
oscillates about a steady mean) as the user's own run would under ``solve``. The stop comes at the end of
the step in which the verdict said so (the solver is paused there); the episode's outcome says which.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from foam_bridge._answer_monitor import AnswerMonitor
from foam_bridge._logparse import LogParser, solved_field_names
from foam_bridge._settle_verdict import SettleRule

__all__ = ["answer_stop", "episode_monitor"]


def episode_monitor(cfg: Any, case_dir: Path, solved_fields: tuple[str, ...]) -> AnswerMonitor | None:
    """The monitor of a new episode's case (``cfg`` a FoamEnvConfig), installed; None without
    ``cfg.settle``."""
    if cfg.settle is None:
        return None
    monitor = AnswerMonitor(case_dir, solved_field_names(solved_fields), cfg.start_time,
                            SettleRule(cfg.settle), ranks=cfg.ranks)
    monitor.install()
    return monitor


def answer_stop(monitor: AnswerMonitor | None, parser: LogParser) -> tuple[str, str] | None:
    """(outcome, cause) where the monitor's verdict ends the episode now (the samples up to the paused
    iteration read), else None."""
    if monitor is None:
        return None
    monitor.poll(parser.iteration + 1)
    verdict = monitor.stop_due
    if verdict is None:
        return None
    worst = max((e for e in verdict.errors().values() if e is not None), default=0.0)
    return verdict.outcome, (f"the answer {verdict.outcome} at iteration {verdict.iteration}: estimated "
                             f"error {worst:.1e}, tolerance {monitor.rule.tolerance:g}")
