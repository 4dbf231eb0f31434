"""How a solver event becomes an episode's outcome: the outcomes an episode ends with, and the
(outcome, cause, K) of a paused or stopped solver, read from its fully parsed output (foam_bridge._env's
docstring describes each end).

Internal to foam_bridge (its users import OUTCOMES, FAILURES and CASE_STOP from ``foam_bridge``); names
here may change.
"""

from __future__ import annotations

import signal
from typing import TYPE_CHECKING

from foam_bridge._solver import DIVERGED, EXITED, HUNG, MISSED, PAUSED

if TYPE_CHECKING:
    from foam_bridge._config import FoamEnvConfig
    from foam_bridge._logparse import LogParser

#: Every value of ``info["outcome"]``.
OUTCOMES = ("running", "converged", "settled", "oscillating", "truncated", "crashed", "diverged", "hung")
#: Outcomes of an episode the answer monitor ended (FoamEnvConfig.settle): its answer settled within the
#: tolerance, or oscillates about a steady mean.
#: Outcomes that are a failure of the solver (terminated, with the failure penalty).
FAILURES = ("crashed", "diverged", "hung")
#: The cause of a "converged" episode that the case's own function object ended (a runTimeControl with
#: ``satisfiedAction end``: its criterion, e.g. a settled force coefficient), followed by its name.
CASE_STOP = "ended by the case's own function object"


def classify(event: str, code: int | None, parser: LogParser, cfg: FoamEnvConfig, target: int
             ) -> tuple[str, str, int]:
    """(outcome, cause, K) of a solver event, from the fully parsed output of a stopped solver.

    A divergence in the log wins over the event that stopped the solver (a watchdog that fired
    while a NaN was still in the pipe is a divergence), so the outcome does not depend on timing.
    """
    if event == PAUSED:
        return "running", "", parser.completed
    if parser.failed_at is not None:
        return "diverged", f"diverged: {parser.diverged}", parser.failed_at
    if event == MISSED or parser.completed > target:
        return "crashed", (f"missed the pause after iteration {target}: the solver went on to "
                           f"iteration {parser.completed} without reading its next factors"), \
            min(parser.completed, target)
    if event == HUNG:
        return "hung", (f"watchdog: no progress within step_timeout_s={cfg.step_timeout_s} s "
                        f"(last iteration started: {parser.iteration})"), parser.iteration
    assert event in (EXITED, DIVERGED)
    if parser.converged_at is not None:
        return "converged", "", parser.converged_at
    if parser.stopped_at is not None and code == 0:  # the case's own criterion, not residualControl's
        return "converged", f"{CASE_STOP} {parser.stopped_by} (runTimeControl)", parser.stopped_at
    if code == 0 and parser.completed >= cfg.max_iterations:
        return "truncated", "", parser.completed
    detail = parser.error or "no error message"
    if code is not None and code < 0:
        detail = f"killed by {signal.Signals(-code).name}; {detail}"
    elif code == 0:
        detail = "it ended without converging before max_iterations"
    cause = f"simpleFoam exited with code {code} at iteration {parser.iteration}: {detail}"
    return "crashed", cause, parser.iteration
